//! A 6-UPS Stewart platform as a [`ConstraintSystem`]: the same engine as the 5-DOF machine,
//! showing that nothing in [`crate::model::closed`] is specific to one mechanism.
//!
//! Leg `i` joins the base joint `U_i` (base frame) to the platform joint `S_i` (platform frame);
//! its length is `L0_i + q_i`:
//!
//! ```text
//! F_i(X, q, θ) = |p + R·S_i − U_i| − (L0_i + q_i) = 0,   i = 1…6.
//! ```
//!
//! Parameters: 42 = 6 × (`S_i` (3), `U_i` (3), `L0_i`), named `S1x … U1x … L01`, leg by leg. The
//! tool frame is the platform frame and the base frame the world frame (both already fixed by the
//! `U_i` and `S_i`, so separate frame errors would be redundant). With full poses measured in the
//! base frame all 42 parameters are identifiable.
//!
//! Default geometry ([`StewartGeometry::default`]): base joints on a circle of radius 200 mm at
//! `0° ± 15°, 120° ± 15°, 240° ± 15°`; platform joints on a circle of 100 mm at
//! `60° ± 45°, 180° ± 45°, 300° ± 45°`, paired so that each leg joins neighbouring groups; home
//! pose `(0, 0, 300 mm, 0, 0, 0)` with `L0_i` the home leg lengths (so `q = 0` at home); strokes
//! `±120 mm`; workspace `x, y ∈ [−40, 40] mm`, `z ∈ [260, 340] mm`, `α, β, γ ∈ [−8°, 8°]`.
use crate::error::{CalibError, KinError};
use crate::model::closed::{v3, ClosedLoop, ConstraintSystem, Scalar, Task, Workspace};
use crate::params::{Param, Unit};

/// Geometry of a 6-UPS platform (mm, rad). Users give their own in a model file
/// (`kind = "stewart"`, see [`crate::io::model_file`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StewartGeometry {
    /// Base joints `U_i` (base frame).
    pub base: [[f64; 3]; 6],
    /// Platform joints `S_i` (platform frame).
    pub platform: [[f64; 3]; 6],
    /// Home platform pose.
    pub home: [f64; 6],
    /// Stroke half-width (mm).
    pub stroke: f64,
    /// Prescribed workspace.
    pub workspace: Workspace,
}

impl Default for StewartGeometry {
    fn default() -> Self {
        let pt = |r: f64, deg: f64| [r * deg.to_radians().cos(), r * deg.to_radians().sin(), 0.0];
        let base_angles = [-15.0, 15.0, 105.0, 135.0, 225.0, 255.0];
        let plat_angles = [-45.0, 45.0, 75.0, 165.0, 195.0, 285.0];
        let base = base_angles.map(|a| pt(200.0, a));
        let platform = plat_angles.map(|a| pt(100.0, a));
        let a = 8f64.to_radians();
        StewartGeometry {
            base,
            platform,
            home: [0.0, 0.0, 300.0, 0.0, 0.0, 0.0],
            stroke: 120.0,
            workspace: Workspace {
                min: [-40.0, -40.0, 260.0, -a, -a, -a],
                max: [40.0, 40.0, 340.0, a, a, a],
            },
        }
    }
}

/// The 6-UPS constraint system.
#[derive(Debug, Clone, PartialEq)]
pub struct Stewart {
    nominal: Vec<f64>,
    home: [f64; 6],
    strokes: [(f64, f64); 6],
    workspace: Workspace,
}

impl Stewart {
    /// A platform of `geometry`; `L0_i` are the leg lengths at the home pose.
    pub fn new(geometry: StewartGeometry) -> Self {
        let h = geometry.home;
        let r = v3::rot_xyz(h[3], h[4], h[5]);
        let mut nominal = Vec::with_capacity(42);
        for i in 0..6 {
            let s = geometry.platform[i];
            let u = geometry.base[i];
            let leg = v3::sub(&v3::add(&[h[0], h[1], h[2]], &v3::mul(&r, &s)), &u);
            nominal.extend_from_slice(&s);
            nominal.extend_from_slice(&u);
            nominal.push(v3::norm(&leg));
        }
        let stroke = (-geometry.stroke, geometry.stroke);
        Stewart {
            nominal,
            home: geometry.home,
            strokes: [stroke; 6],
            workspace: geometry.workspace,
        }
    }

    /// A platform of arbitrary geometry: the 42 absolute values `θ` in the order of the
    /// parameters (leg by leg `S_i` (3), `U_i` (3), `L0_i`), e.g. a calibrated geometry, with its
    /// home pose, per-leg strokes `(min, max)` of `q_i` (mm) and workspace. Errors: wrong length,
    /// a non-finite value, an empty stroke or workspace.
    pub fn from_parameters(theta: Vec<f64>, home: [f64; 6], strokes: [(f64, f64); 6], workspace: Workspace) -> Result<Self, CalibError> {
        if theta.len() != 42 {
            return Err(CalibError::InvalidOption(format!(
                "Stewart geometry: {} values, expected 42",
                theta.len()
            )));
        }
        if theta.iter().chain(home.iter()).any(|v| !v.is_finite()) {
            return Err(CalibError::InvalidOption("Stewart geometry: non-finite value".into()));
        }
        if strokes.iter().any(|(lo, hi)| !(lo.is_finite() && hi.is_finite() && lo < hi)) {
            return Err(CalibError::InvalidOption(
                "Stewart geometry: every stroke needs finite min < max".into(),
            ));
        }
        if (0..6).any(|i| workspace.min[i].partial_cmp(&workspace.max[i]).is_none_or(|o| o.is_gt())) {
            return Err(CalibError::InvalidOption(
                "Stewart geometry: workspace min must not exceed max".into(),
            ));
        }
        Ok(Stewart {
            nominal: theta,
            home,
            strokes,
            workspace,
        })
    }

    /// The calibratable mechanism (42 parameters, tool = platform frame, base = world frame).
    pub fn mechanism(geometry: StewartGeometry) -> ClosedLoop<Stewart> {
        Self::mechanism_of(Stewart::new(geometry))
    }

    /// The calibratable mechanism of a platform, e.g. one of [`Stewart::from_parameters`].
    pub fn mechanism_of(system: Stewart) -> ClosedLoop<Stewart> {
        ClosedLoop::new(system, [0.0; 3], false)
    }
}

fn leg_vector<D: Scalar>(x: &[D; 6], t: &[D]) -> v3::V3<D> {
    let r = v3::rot_xyz(x[3], x[4], x[5]);
    v3::sub(
        &v3::add(&[x[0], x[1], x[2]], &v3::mul(&r, &[t[0], t[1], t[2]])),
        &[t[3], t[4], t[5]],
    )
}

impl ConstraintSystem for Stewart {
    fn name(&self) -> &str {
        "stewart"
    }
    fn input_names(&self) -> Vec<String> {
        (1..=6).map(|i| format!("q{i}")).collect()
    }
    fn geometry_params(&self) -> Vec<Param> {
        let mut p = Vec::with_capacity(42);
        for i in 1..=6 {
            let g = format!("leg {i}");
            for n in ["S", "U"] {
                for a in ["x", "y", "z"] {
                    p.push(Param::new(format!("{n}{i}{a}"), Unit::Length, g.clone()));
                }
            }
            p.push(Param::new(format!("L0{i}"), Unit::Length, g));
        }
        p
    }
    fn nominal_geometry(&self) -> Vec<f64> {
        self.nominal.clone()
    }
    fn equations<D: Scalar>(&self, x: &[D; 6], q: &[D], t: &[D]) -> [D; 6] {
        std::array::from_fn(|i| {
            let ti = &t[7 * i..7 * i + 7];
            v3::norm(&leg_vector(x, ti)) - (ti[6] + q[i])
        })
    }
    fn inputs_for_pose(&self, x: &[f64; 6], t: &[f64]) -> Result<Vec<f64>, KinError> {
        Ok((0..6)
            .map(|i| {
                let ti = &t[7 * i..7 * i + 7];
                v3::norm(&leg_vector(x, ti)) - ti[6]
            })
            .collect())
    }
    fn task(&self) -> Task {
        Task::Full
    }
    fn home(&self) -> [f64; 6] {
        self.home
    }
    fn strokes(&self) -> Vec<(f64, f64)> {
        self.strokes.to_vec()
    }
    fn workspace(&self) -> Workspace {
        self.workspace.clone()
    }
}
