//! Where candidate configurations are sampled, as command-line arguments ([`SamplingArgs`],
//! flattened into `kinecal plan`), parsed into the library's description
//! ([`CandidateSampling`]). What a box of poses means for each mechanism, and its defaults when a
//! range is not given, are the library's ([`kinecal::design::sampling`]).
use clap::Args;
use kinecal::design::{CandidateSampling, Points, PoseRanges, Region};

/// The sampling arguments.
#[derive(Args, Debug)]
pub struct SamplingArgs {
    /// Workspace range of x, "MIN,MAX" or a fixed "VALUE" (mm).
    #[arg(long, allow_hyphen_values = true, value_parser = range)]
    pub x_mm: Option<(f64, f64)>,
    /// Workspace range of y (mm).
    #[arg(long, allow_hyphen_values = true, value_parser = range)]
    pub y_mm: Option<(f64, f64)>,
    /// Workspace range of z (mm).
    #[arg(long, allow_hyphen_values = true, value_parser = range)]
    pub z_mm: Option<(f64, f64)>,
    /// Range of α (pm5: platform X-Y-Z Euler angle α; model: roll about world x) (degrees;
    /// also --roll-deg, the name the printed workspace uses).
    #[arg(long, visible_alias = "roll-deg", allow_hyphen_values = true, value_parser = range)]
    pub alpha_deg: Option<(f64, f64)>,
    /// Range of β (pm5: Euler angle β; model: pitch about world y) (degrees; also --pitch-deg).
    #[arg(long, visible_alias = "pitch-deg", allow_hyphen_values = true, value_parser = range)]
    pub beta_deg: Option<(f64, f64)>,
    /// Range of γ (model: yaw about world z; pm5: parasitic, must be a fixed value) (degrees;
    /// also --yaw-deg).
    #[arg(long, visible_alias = "yaw-deg", allow_hyphen_values = true, value_parser = range)]
    pub gamma_deg: Option<(f64, f64)>,
    /// Sample the workspace on a full grid "N1,N2,…" (one count per coordinate x, y, z, α, β, γ;
    /// pm5 default grid with --grid paper: 11,11,21,12,10,1 = 304,920 points) instead of Halton
    /// points.
    #[arg(long, value_parser = grid)]
    pub grid: Option<Points>,
    /// Number of candidate samples (Halton points).
    #[arg(long, default_value_t = 300_000)]
    pub candidates: usize,
    /// Joint range ± (degrees) of the candidates.
    #[arg(long, default_value_t = 170.0)]
    pub joint_range_deg: f64,
    /// Largest condition number of the input Jacobian (orientation rows × 100 mm) a candidate may
    /// have; none by default (pm5: 100).
    #[arg(long)]
    pub max_condition: Option<f64>,
    /// Seed of the Halton shift (candidate sample).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// A range "MIN,MAX" or a fixed "VALUE".
pub(crate) fn range(text: &str) -> Result<(f64, f64), String> {
    let v: Result<Vec<f64>, _> = text.split(',').map(|t| t.trim().parse()).collect();
    match v.as_deref() {
        Ok(&[a]) if a.is_finite() => Ok((a, a)),
        Ok(&[a, b]) if a.is_finite() && b.is_finite() && a <= b => Ok((a, b)),
        _ => Err(format!("expected MIN,MAX (finite, MIN ≤ MAX) or VALUE, got '{text}'")),
    }
}

/// A grid "N1,…,N6", or "paper".
fn grid(text: &str) -> Result<Points, String> {
    if text == "paper" {
        return Ok(Points::PaperGrid);
    }
    let counts: Result<Vec<usize>, _> = text.split(',').map(|t| t.trim().parse()).collect();
    counts
        .map(|counts| Points::Grid { counts })
        .map_err(|_| format!("expected six counts N1,…,N6 or 'paper', got '{text}'"))
}

impl SamplingArgs {
    /// The description of the arguments: a box of poses, or with `joint_space` (a number of
    /// inputs) the box ±`--joint-range-deg` of every input.
    pub fn sampling(&self, joint_space: Option<usize>) -> CandidateSampling {
        let rad = |r: Option<(f64, f64)>| r.map(|(a, b)| (a.to_radians(), b.to_radians()));
        let lim = self.joint_range_deg.to_radians();
        let region = match joint_space {
            Some(n) => Region::Inputs {
                lower: vec![-lim; n],
                upper: vec![lim; n],
            },
            None => Region::Poses(PoseRanges {
                position: [self.x_mm, self.y_mm, self.z_mm],
                angles: [rad(self.alpha_deg), rad(self.beta_deg), rad(self.gamma_deg)],
            }),
        };
        let points = self.grid.clone().unwrap_or(Points::Halton {
            n: self.candidates,
            seed: self.seed,
        });
        CandidateSampling {
            region,
            points,
            max_condition: self.max_condition,
        }
    }
}
