//! Virtual prototypes: random geometric errors, synthetic measurements with noise, random chains.
//!
//! Every random draw takes an explicit seed or RNG, so the same inputs give the same outputs.
use crate::error::{CalibError, KinError};
use crate::measure::{Measurement, Noise, Observation};
use crate::model::chain::{ChainJoint, SerialChain};
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::params::Unit;
use crate::se3::{self, Pose};
use nalgebra::{DVector, Vector3};
use rand::{Rng, RngExt};
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;

/// Uniform random error coordinates: lengths in `±length` (mm), angles in `±angle` (rad),
/// dimensionless ones in `±length`. Only the parameters in `which` (default: all) are drawn.
pub fn random_errors<M: Mechanism + ?Sized, R: Rng>(
    model: &M,
    rng: &mut R,
    length: f64,
    angle: f64,
    which: Option<&[usize]>,
) -> DVector<f64> {
    let params = model.params();
    let mut d = DVector::zeros(params.len());
    let all: Vec<usize> = (0..params.len()).collect();
    for &i in which.unwrap_or(&all) {
        let r = match params[i].unit {
            Unit::Angle => angle,
            _ => length,
        };
        d[i] = rng.random_range(-1.0..=1.0) * r;
    }
    d
}

/// A copy of `model` with the error `delta` applied (a virtual prototype's "true" geometry).
pub fn perturbed<M: Mechanism + Clone>(model: &M, delta: &DVector<f64>) -> M {
    let mut m = model.clone();
    m.retract(delta);
    m
}

/// Kind of synthetic observation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObservationKind {
    /// Full tool pose.
    Pose,
    /// Tool-frame origin position.
    Position,
}

impl std::str::FromStr for ObservationKind {
    type Err = String;
    /// `pose` or `position`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "pose" => Ok(ObservationKind::Pose),
            "position" => Ok(ObservationKind::Position),
            o => Err(format!("must be pose or position, got '{o}'")),
        }
    }
}

/// Measure `truth` at each input vector, adding Gaussian noise (`None`: noise-free). The noise is
/// applied as a position offset `N(0, σ_p²)` per axis and a rotation vector `N(0, σ_θ²)` per axis.
pub fn measure<M: Mechanism + ?Sized, R: Rng>(
    truth: &M,
    inputs: &[Vec<f64>],
    kind: ObservationKind,
    noise: Option<&Noise>,
    rng: &mut R,
) -> Result<Vec<Measurement>, CalibError> {
    let mut out = Vec::with_capacity(inputs.len());
    for (i, q) in inputs.iter().enumerate() {
        let (t, values) = truth
            .forward_and_observed(q)
            .map_err(|source| CalibError::Kinematics { pose: i, source })?;
        let (dp, dw) = match noise {
            Some(n) => {
                let np = Normal::new(0.0, n.position).map_err(|e| CalibError::InvalidOption(e.to_string()))?;
                let nw = Normal::new(0.0, n.orientation).map_err(|e| CalibError::InvalidOption(e.to_string()))?;
                (
                    Vector3::new(np.sample(rng), np.sample(rng), np.sample(rng)),
                    Vector3::new(nw.sample(rng), nw.sample(rng), nw.sample(rng)),
                )
            }
            None => (Vector3::zeros(), Vector3::zeros()),
        };
        let obs = match kind {
            ObservationKind::Pose => {
                Observation::Pose(Pose::from_parts((t.translation.vector + dp).into(), se3::so3_exp(&dw) * t.rotation))
            }
            ObservationKind::Position => Observation::Position(t.translation.vector + dp),
        };
        let exact = Noise {
            joint_angle: 0.0,
            joint_length: 0.0,
            ..Noise::default()
        };
        let joints = observed_readings(truth, values, noise.unwrap_or(&exact), rng)?;
        out.push(Measurement { joints, q: q.clone(), obs });
    }
    Ok(out)
}

/// The readings of `truth`'s observed joints: their `values` with Gaussian noise of
/// [`Noise::joint_angle`] / [`Noise::joint_length`] (0: none); nothing drawn without observed
/// joints.
pub fn observed_readings<M: Mechanism + ?Sized, R: Rng>(
    truth: &M,
    mut values: Vec<f64>,
    noise: &Noise,
    rng: &mut R,
) -> Result<Vec<f64>, CalibError> {
    for (x, (_, u)) in values.iter_mut().zip(&truth.observed_joints()) {
        let s = if *u == crate::params::Unit::Angle {
            noise.joint_angle
        } else {
            noise.joint_length
        };
        if s > 0.0 {
            *x += Normal::new(0.0, s)
                .map_err(|e| CalibError::InvalidOption(format!("encoder noise σ {s}: {e}")))?
                .sample(rng);
        }
    }
    Ok(values)
}

/// A random serial chain with `revolute` + `prismatic` joints in random order, random joint axes
/// and link offsets of a few hundred millimetres (for tests and benchmarks).
pub fn random_serial_chain<R: Rng>(rng: &mut R, revolute: usize, prismatic: usize) -> SerialChain {
    let mut kinds: Vec<bool> = std::iter::repeat_n(true, revolute)
        .chain(std::iter::repeat_n(false, prismatic))
        .collect();
    // Fisher–Yates with the given RNG.
    for i in (1..kinds.len()).rev() {
        let j = rng.random_range(0..=i);
        kinds.swap(i, j);
    }
    let mut rand_vec = |s: f64| Vector3::new(rng.random_range(-s..s), rng.random_range(-s..s), rng.random_range(-s..s));
    let mut joints = Vec::new();
    let mut initial = Vec::new();
    for (j, &rev) in kinds.iter().enumerate() {
        let axis = rand_vec(1.0).normalize();
        let name = format!("q{}", j + 1);
        joints.push(if rev {
            ChainJoint::revolute(name, axis)
        } else {
            ChainJoint::prismatic(name, axis)
        });
        initial.push(se3::pose_from_parts(rand_vec(300.0), rand_vec(1.5)));
    }
    let tool = se3::pose_from_parts(rand_vec(100.0), rand_vec(1.5));
    SerialChain::new(format!("random-{revolute}r{prismatic}p"), joints, initial, tool)
}

/// Random joint values: revolute in `±angle` rad, prismatic in `±length` mm.
pub fn random_joint_values<R: Rng>(chain: &SerialChain, rng: &mut R, angle: f64, length: f64) -> Vec<f64> {
    chain
        .joints()
        .iter()
        .map(|j| match j.kind {
            crate::model::chain::JointKind::Revolute => rng.random_range(-angle..angle),
            crate::model::chain::JointKind::Prismatic => rng.random_range(-length..length),
        })
        .collect()
}

/// The range an input is drawn from: its limits, or ±π rad / ±100 mm without limits.
pub fn input_range(input: &InputSpec) -> (f64, f64) {
    input.limits.unwrap_or(match input.unit {
        Unit::Angle => (-PI, PI),
        _ => (-100.0, 100.0),
    })
}

/// `n` random input vectors, uniform within [`input_range`] of each input.
pub fn random_inputs<R: Rng>(inputs: &[InputSpec], n: usize, rng: &mut R) -> Vec<Vec<f64>> {
    let mut out: Vec<Vec<f64>> = (0..n)
        .map(|_| {
            inputs
                .iter()
                .map(|i| match i.approach_of {
                    Some(_) => 0.0,
                    None => {
                        let (lo, hi) = input_range(i);
                        rng.random_range(lo..hi)
                    }
                })
                .collect()
        })
        .collect();
    // Approach directions: those of visiting the configurations in the order drawn.
    crate::model::kind::approach_from_order(inputs, &vec![false; inputs.len()], &mut out);
    out
}

/// `n` input vectors at which `model` assembles: the mechanism's own draw
/// ([`Mechanism::sample_configurations`]: closed loops draw platform poses uniformly in their
/// workspace and solve the inverse kinematics) when it has one, else inputs uniform within
/// [`input_range`] ([`random_inputs`], drawn from `rng` directly). Reproducible: for a mechanism
/// that draws its own, one `u64` is drawn from `rng` as its seed.
pub fn random_configurations<M: Mechanism + ?Sized, R: Rng>(
    model: &M,
    inputs: &[InputSpec],
    n: usize,
    rng: &mut R,
) -> Result<Vec<Vec<f64>>, KinError> {
    // Asking for no configurations tells whether the mechanism draws its own, without using rng.
    if model.sample_configurations(0, 0).is_none() {
        return Ok(random_inputs(inputs, n, rng));
    }
    let seed: u64 = rng.random();
    model
        .sample_configurations(n, seed)
        .unwrap_or_else(|| Ok(random_inputs(inputs, n, rng)))
}

/// Reflector centres (mm) in the tool frame used for simulated three-reflector measurements:
/// their frame ([`crate::measure::frame_from_reflectors`]) *is* the tool frame (centroid at the origin,
/// `M2 − M3` along x, `M1` on +y).
pub const REFLECTORS: [[f64; 3]; 3] = [[0.0, 60.0, 0.0], [40.0, -30.0, 0.0], [-40.0, -30.0, 0.0]];

/// The three reflector centres of [`REFLECTORS`] seen at tool pose `t`, each with Gaussian
/// position noise `sigma_mm` per axis (0: none).
pub fn reflector_centres<R: Rng>(t: &Pose, sigma_mm: f64, rng: &mut R) -> Result<[Vector3<f64>; 3], CalibError> {
    let normal = Normal::new(0.0, sigma_mm).map_err(|e| CalibError::InvalidOption(e.to_string()))?;
    let mut out = [Vector3::zeros(); 3];
    for (k, r) in REFLECTORS.iter().enumerate() {
        let p = t.transform_point(&Vector3::from(*r).into()).coords;
        let n = if sigma_mm > 0.0 {
            Vector3::new(normal.sample(rng), normal.sample(rng), normal.sample(rng))
        } else {
            Vector3::zeros()
        };
        out[k] = p + n;
    }
    Ok(out)
}

/// A virtual prototype: the nominal model with uniform random errors on the parameters `which`
/// (lengths in `±length_mm`, angles in `±angle_rad`). Returns the "true" model and the error.
pub fn virtual_prototype<M: Mechanism + Clone, R: Rng>(
    nominal: &M,
    which: &[usize],
    length_mm: f64,
    angle_rad: f64,
    rng: &mut R,
) -> (M, DVector<f64>) {
    let delta = crate::simulate::random_errors(nominal, rng, length_mm, angle_rad, Some(which));
    (crate::simulate::perturbed(nominal, &delta), delta)
}

/// Default noise when neither the command line nor the model file gives one.
pub fn default_noise() -> Noise {
    Noise::default()
}

/// What a simulated instrument measures (see [`synthesize`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Instrument {
    /// The tool pose, noise on the position (mm per axis) and on the orientation (rotation vector,
    /// rad per axis).
    Pose,
    /// The tool-frame origin, noise in mm per axis.
    Position,
    /// The three reflector centres of [`REFLECTORS`] in the tool frame, each with position noise;
    /// the observation is their frame ([`crate::measure::frame_from_reflectors`]).
    Reflectors,
}

/// Synthetic measurements of a virtual prototype: [`Measurement`]s in order, and for
/// [`Instrument::Reflectors`] the raw reflector centres of each pose (what a data file stores).
#[derive(Debug, Clone)]
pub struct SyntheticSet {
    /// One measurement per configuration, in order.
    pub measurements: Vec<Measurement>,
    /// The three reflector centres per pose (mm), only for [`Instrument::Reflectors`].
    pub reflectors: Option<Vec<[Vector3<f64>; 3]>>,
}

/// Measure `truth` at each configuration with `instrument` and Gaussian `noise` (σ 0: none),
/// drawing from `rng` (same seed, same data). `progress` is called once per pose. A configuration
/// the prototype does not reach is [`CalibError::Kinematics`] with its index.
pub fn synthesize<M: Mechanism + ?Sized, R: Rng>(
    truth: &M,
    configurations: Vec<Vec<f64>>,
    instrument: Instrument,
    noise: &Noise,
    rng: &mut R,
    progress: &dyn Fn(usize),
) -> Result<SyntheticSet, CalibError> {
    let normal = |s: f64| Normal::new(0.0, s).map_err(|e| CalibError::InvalidOption(format!("noise σ {s}: {e}")));
    let (np, nw) = (normal(noise.position)?, normal(noise.orientation)?);
    let mut measurements = Vec::with_capacity(configurations.len());
    let mut reflectors = Vec::new();
    for (k, q) in configurations.into_iter().enumerate() {
        let (t, values) = truth
            .forward_and_observed(&q)
            .map_err(|source| CalibError::Kinematics { pose: k, source })?;
        let mut draw = |d: &Normal<f64>, s: f64| {
            if s > 0.0 {
                Vector3::new(d.sample(rng), d.sample(rng), d.sample(rng))
            } else {
                Vector3::zeros()
            }
        };
        let obs = match instrument {
            Instrument::Pose => {
                let (dp, dw) = (draw(&np, noise.position), draw(&nw, noise.orientation));
                Observation::Pose(Pose::from_parts((t.translation.vector + dp).into(), se3::so3_exp(&dw) * t.rotation))
            }
            Instrument::Position => Observation::Position(t.translation.vector + draw(&np, noise.position)),
            Instrument::Reflectors => {
                let c = reflector_centres(&t, noise.position, rng)?;
                let f = crate::measure::frame_from_reflectors(&c[0], &c[1], &c[2])
                    .ok_or_else(|| CalibError::InvalidOption(format!("pose {k}: degenerate reflector triangle")))?;
                reflectors.push(c);
                Observation::Pose(f)
            }
        };
        let joints = observed_readings(truth, values, noise, rng)?;
        measurements.push(Measurement { joints, q, obs });
        progress(k);
    }
    Ok(SyntheticSet {
        measurements,
        reflectors: (instrument == Instrument::Reflectors).then_some(reflectors),
    })
}
