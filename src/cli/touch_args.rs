//! The touch-probe options `kinecal simulate` and `kinecal plan` share: reference spheres,
//! unknown planes or a datum cube, and the probe's tip radius, parsed into
//! [`kinecal::instrument::simulate::Touched`] artifacts.
use clap::Args;
use kinecal::instrument::simulate::{parse_points, TouchSpec, Touched};

/// Spheres, planes or a datum cube touched by a probe.
#[derive(Args, Debug, Clone, Default)]
pub struct TouchArgs {
    /// Touch-probe data: reference spheres centred at these points (mm, base frame,
    /// `X,Y,Z;…`), each touched `--per-point` times at the random configurations nearest its
    /// surface, moved onto it; columns `sphere,sphere_diameter_mm,probe_radius_mm`. Needs
    /// `--sphere-diameter-mm` and `--probe-radius-mm`.
    #[arg(long, value_name = "X,Y,Z;…", requires = "sphere_diameter_mm", conflicts_with_all = ["seats", "pivots", "planes", "cube"])]
    pub spheres: Option<String>,
    /// The reference spheres' diameter (mm).
    #[arg(long, value_name = "D", requires = "spheres")]
    pub sphere_diameter_mm: Option<f64>,
    /// Touch-probe data: planes through these points (mm, base frame, `X,Y,Z;…`), their normals
    /// `--plane-normals`, each touched `--per-point` times; columns `plane,probe_radius_mm`.
    /// With `kinecal simulate`, `--pivots` may add a ballbar's lengths to the same file (a
    /// printer's bed touches and a few lengths).
    #[arg(long, value_name = "X,Y,Z;…", requires = "plane_normals", conflicts_with_all = ["seats", "cube"])]
    pub planes: Option<String>,
    /// The planes' normals (`NX,NY,NZ;…`, one per plane; normalised).
    #[arg(long, value_name = "NX,NY,NZ;…", allow_hyphen_values = true, requires = "planes")]
    pub plane_normals: Option<String>,
    /// Touch-probe data: a datum cube centred here (mm, base frame, `X,Y,Z`), its edges along the
    /// base axes turned by `--cube-rotation-deg`; each face (0..5: +x, −x, +y, −y, +z, −z)
    /// touched `--per-point` times; columns `face,cube_edge_mm,probe_radius_mm`.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true, requires = "cube_edge_mm", conflicts_with_all = ["seats", "pivots"])]
    pub cube: Option<String>,
    /// The datum cube's edge (mm).
    #[arg(long, value_name = "E", requires = "cube")]
    pub cube_edge_mm: Option<f64>,
    /// The datum cube's orientation: a rotation vector (degrees, `RX,RY,RZ`).
    #[arg(long, value_name = "RX,RY,RZ", allow_hyphen_values = true, requires = "cube")]
    pub cube_rotation_deg: Option<String>,
    /// The touch probe's tip radius (mm; 0 for a pointed tip).
    #[arg(long, value_name = "R")]
    pub probe_radius_mm: Option<f64>,
}

impl TouchArgs {
    /// Whether spheres, planes or a cube are given.
    pub fn active(&self) -> bool {
        self.spheres.is_some() || self.planes.is_some() || self.cube.is_some()
    }

    /// The options as typed, for a command line to repeat (`--spheres "…" --sphere-diameter-mm D
    /// --probe-radius-mm R`).
    pub fn command_line(&self) -> String {
        let mut out = Vec::new();
        let mut push = |name: &str, v: Option<String>| match v {
            Some(v) if v.contains(';') => out.push(format!("--{name} \"{v}\"")),
            Some(v) => out.push(format!("--{name} {v}")),
            None => {}
        };
        push("spheres", self.spheres.clone());
        push("sphere-diameter-mm", self.sphere_diameter_mm.map(|v| v.to_string()));
        push("planes", self.planes.clone());
        push("plane-normals", self.plane_normals.clone());
        push("cube", self.cube.clone());
        push("cube-edge-mm", self.cube_edge_mm.map(|v| v.to_string()));
        push("cube-rotation-deg", self.cube_rotation_deg.clone());
        push("probe-radius-mm", self.probe_radius_mm.map(|v| v.to_string()));
        out.join(" ")
    }

    /// The artifacts: their kind's name (`sphere`, `plane`, `cube face`), one [`Touched`] per
    /// sphere, plane or cube face, and the probe radius (mm), through
    /// [`kinecal::instrument::simulate::TouchSpec::artifacts`]; its one-line errors are prefixed
    /// with the options they concern.
    pub fn artifacts(&self) -> anyhow::Result<(&'static str, Vec<Touched>, f64)> {
        let probe = self.probe_radius_mm.filter(|r| r.is_finite() && *r >= 0.0).ok_or_else(|| {
            anyhow::anyhow!("--probe-radius-mm: the radius of the probe's tip ball is needed (mm, not negative; 0 for a pointed tip)")
        })?;
        let parse = |option: &str, text: &str| parse_points(text).map_err(|e| anyhow::anyhow!("{option} {e}"));
        let mut spec = TouchSpec {
            probe_radius_mm: probe,
            sphere_diameter_mm: self.sphere_diameter_mm,
            ..TouchSpec::default()
        };
        let options = if let Some(text) = &self.spheres {
            spec.spheres = parse("--spheres", text)?;
            "--spheres/--sphere-diameter-mm"
        } else if let Some(text) = &self.planes {
            let origins = parse("--planes", text)?;
            let normals = parse("--plane-normals", self.plane_normals.as_deref().unwrap_or_default())?;
            anyhow::ensure!(
                normals.len() == origins.len(),
                "--plane-normals: {} normals for {} planes",
                normals.len(),
                origins.len()
            );
            spec.planes = origins.into_iter().zip(normals).collect();
            "--planes/--plane-normals"
        } else {
            let text = self
                .cube
                .as_deref()
                .ok_or_else(|| anyhow::anyhow!("touches need --spheres, --planes or --cube"))?;
            let [centre] = parse("--cube", text)?
                .try_into()
                .map_err(|_| anyhow::anyhow!("--cube '{text}': one point X,Y,Z (mm)"))?;
            let rotation = match &self.cube_rotation_deg {
                Some(r) => {
                    let [v] = parse("--cube-rotation-deg", r)?
                        .try_into()
                        .map_err(|_| anyhow::anyhow!("--cube-rotation-deg '{r}': RX,RY,RZ (deg)"))?;
                    v.map(f64::to_radians)
                }
                None => nalgebra::Vector3::zeros(),
            };
            spec.cube = Some((centre, rotation, self.cube_edge_mm.unwrap_or(f64::NAN)));
            "--cube/--cube-edge-mm"
        };
        let (kind, artifacts) = spec.artifacts().map_err(|e| match e {
            kinecal::CalibError::InvalidOption(m) => anyhow::anyhow!("{options}: {m}"),
            e => anyhow::anyhow!("{options}: {e}"),
        })?;
        Ok((kind, artifacts, probe))
    }
}
