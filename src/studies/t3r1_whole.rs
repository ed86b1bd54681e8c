//! The §6 study of the 3T1R paper run on the **whole machine's model file** (`t3r1`,
//! `examples/models/t3r1.toml`, or a user's edit of it) through the general library: the same
//! simulated actual machine, the same identification and validation poses and the same tracker
//! noise as the paper's method ([`crate::studies::t3r1`]), identified with
//! [`crate::identify::identify`] from the four slider readings and the measured poses, validated
//! with [`crate::validate`] and compensated with [`crate::compensate::compensate`].
//!
//! The difference from the paper's method is what the prediction rests on: the pair of chains
//! predicts a pose from the sensed passive angles (their encoder noise enters the prediction),
//! the model file's closure predicts it from the sliders alone, as the machine is commanded.
use crate::error::CalibError;
use crate::identify::{self, Options};
use crate::io::model_file::ModelFile;
use crate::measure::{Measurement, Noise, Observation};
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::se3::Pose;
use crate::studies::t3r1_machine::{tilt, ActualMachine, PlatformPose};
use crate::validate::{self, ErrorStats};
use serde::Serialize;

/// Compensation results on the validation targets (§7).
#[derive(Debug, Clone, PartialEq, Serialize, Default)]
pub struct CompensationStats {
    /// Largest position error of the actual machine at the nominal slider commands (mm).
    pub before_position_mm: f64,
    /// Largest yaw error at the nominal commands (deg).
    pub before_yaw_deg: f64,
    /// Largest position error at the compensated commands (mm).
    pub after_position_mm: f64,
    /// Largest yaw error at the compensated commands (deg).
    pub after_yaw_deg: f64,
    /// Platform tilt of the actual machine (largest, deg): a 3T1R machine cannot remove it.
    pub tilt_deg: f64,
    /// Largest position change `|T_cp − T_co|` of the programmed pose (mm).
    pub program_change_mm: f64,
}

impl CompensationStats {
    /// Account for one target: the pose the nominal commands reach (`before`), the pose the
    /// compensated commands reach on the actual machine (`reached`) and how far the programmed
    /// pose moved (`program_change_mm`).
    pub fn add(&mut self, target: &PlatformPose, before: &Pose, reached: &Pose, program_change_mm: f64) {
        let err = |t: &Pose| {
            let p = PlatformPose::from_pose(t);
            let dp = nalgebra::Vector3::new(p.x - target.x, p.y - target.y, p.z - target.z).norm();
            (dp, (p.yaw - target.yaw).abs().to_degrees())
        };
        let (bp, by) = err(before);
        let (cp, cy) = err(reached);
        self.before_position_mm = self.before_position_mm.max(bp);
        self.before_yaw_deg = self.before_yaw_deg.max(by);
        self.after_position_mm = self.after_position_mm.max(cp);
        self.after_yaw_deg = self.after_yaw_deg.max(cy);
        self.tilt_deg = self.tilt_deg.max(tilt(reached).to_degrees());
        self.program_change_mm = self.program_change_mm.max(program_change_mm);
    }
}

/// The model file and its free parameters.
pub struct WholeMachine {
    /// The model (nominal geometry).
    pub model: Box<dyn Mechanism>,
    /// Free parameters (the file's `[calibration]`).
    pub free: Vec<usize>,
    /// The model's inputs (names, units, limits).
    pub inputs: Vec<InputSpec>,
    /// For each model input, the study's slider index (`s1` → 0 … `s4` → 3).
    pub slider_of_input: Vec<usize>,
    /// For each observed joint of the model, the study's encoder it reads.
    pub encoder_of_observed: Vec<Encoder>,
}

/// An encoder of the study's machine.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoder {
    /// The upper-parallelogram angle of chain `B1..B4` (`u1`…`u4`).
    Upper(usize),
    /// The platform revolute of chain `B1` or `B3` (`r1`, `r3`).
    Platform(usize),
}

/// The encoder readings of one pose (rad): upper angles `B1..B4`, platform revolutes `B1`, `B3`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EncoderReadings {
    /// Upper-parallelogram angles of `B1..B4`.
    pub upper: [f64; 4],
    /// Platform revolutes of `B1`, `B3`.
    pub platform: [f64; 2],
}

impl WholeMachine {
    /// The study's machine from a model file (built-in `t3r1` or a user's edit): its inputs
    /// must be the four sliders `s1`…`s4` (any order).
    pub fn from_file(file: &ModelFile) -> Result<Self, CalibError> {
        let invalid = |e: crate::io::IoError| CalibError::InvalidOption(e.to_string());
        Self::new(file.build(), file.free_indices().map_err(invalid)?, file.inputs())
    }

    /// The study's machine as `model` with `free` parameters and `inputs`: its inputs must be
    /// the four sliders `s1`…`s4` (any order).
    pub fn new(model: Box<dyn Mechanism>, free: Vec<usize>, inputs: Vec<InputSpec>) -> Result<Self, CalibError> {
        let names = model.input_names();
        let slider_of_input: Vec<usize> = names
            .iter()
            .filter_map(|n| match n.as_str() {
                "s1" => Some(0),
                "s2" => Some(1),
                "s3" => Some(2),
                "s4" => Some(3),
                _ => None,
            })
            .collect();
        let mut sorted = slider_of_input.clone();
        sorted.sort_unstable();
        if names.len() != 4 || sorted != [0, 1, 2, 3] {
            return Err(CalibError::InvalidOption(format!(
                "the study's machine model must be actuated by the four sliders named s1, s2, s3, s4 (the chains B1..B4), but its inputs are: {}",
                names.join(", ")
            )));
        }
        let encoder_of_observed = model
            .observed_joints()
            .into_iter()
            .map(|(n, _)| match n.as_str() {
                "u1" => Ok(Encoder::Upper(0)),
                "u2" => Ok(Encoder::Upper(1)),
                "u3" => Ok(Encoder::Upper(2)),
                "u4" => Ok(Encoder::Upper(3)),
                "r1" => Ok(Encoder::Platform(0)),
                "r3" => Ok(Encoder::Platform(1)),
                other => Err(CalibError::InvalidOption(format!(
                    "the study's machine model observes joint '{other}', which the study has no encoder for (its encoders: u1..u4, r1, r3)"
                ))),
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(WholeMachine {
            model,
            free,
            inputs,
            slider_of_input,
            encoder_of_observed,
        })
    }

    /// The model's input vector for the study's sliders (`B1..B4`).
    pub fn inputs(&self, sliders: &[f64; 4]) -> Vec<f64> {
        self.slider_of_input.iter().map(|&k| sliders[k]).collect()
    }

    /// The model's observed-joint readings from the study's encoders.
    pub fn readings(&self, r: &EncoderReadings) -> Vec<f64> {
        self.encoder_of_observed
            .iter()
            .map(|e| match *e {
                Encoder::Upper(k) => r.upper[k],
                Encoder::Platform(k) => r.platform[k],
            })
            .collect()
    }

    /// The study's sliders (`B1..B4`) for a model input vector.
    pub fn sliders(&self, q: &[f64]) -> [f64; 4] {
        let mut s = [0.0; 4];
        for (v, &k) in q.iter().zip(&self.slider_of_input) {
            s[k] = *v;
        }
        s
    }
}

/// One pose of the study as the model file sees it.
#[derive(Debug, Clone, PartialEq)]
pub struct SliderPose {
    /// Slider readings `B1..B4` (mm; exact).
    pub sliders: [f64; 4],
    /// The pose: measured (identification, with the tracker's noise) or true (validation).
    pub pose: Pose,
    /// The commanded pose the sliders were computed for (nominal inverse).
    pub target: PlatformPose,
    /// The encoders' readings, when they are data (identification poses).
    pub encoders: Option<EncoderReadings>,
}

/// The study's case on the whole machine's model file.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WholeMachineCase {
    /// Error parameters of the model.
    pub params: usize,
    /// Free parameters.
    pub free: usize,
    /// The observed joints whose encoder readings were data (their noise the weight).
    pub observed: Vec<String>,
    /// Identifiable parameters at the identification poses (the rank).
    pub rank: usize,
    /// Identifiable parameters at the identification and validation poses together: what more
    /// poses identify.
    pub full_rank: usize,
    /// Gauss–Newton iterations.
    pub iterations: usize,
    /// Whether the fit converged.
    pub converged: bool,
    /// `σ̂₀` of the fit (1 when the weights are the noise).
    pub sigma0: f64,
    /// Errors of the nominal model on the validation poses (true poses).
    pub nominal_validation: ErrorStats,
    /// Errors on the validation poses after one Gauss–Newton iteration (the paper's "one
    /// iteration" figure, on the general path).
    pub one_iteration: ErrorStats,
    /// Errors of the calibrated model on the validation poses.
    pub validation: ErrorStats,
    /// Compensation of the validation targets through the general `compensate`, checked on the
    /// actual machine.
    pub compensation: CompensationStats,
}

impl WholeMachineCase {
    /// Why the fit cannot be trusted, if it cannot.
    pub fn failure(&self) -> Option<String> {
        if !self.converged {
            return Some(format!("the model file's fit did not converge in {} iterations", self.iterations));
        }
        (self.rank < self.full_rank).then(|| {
            format!(
                "the identification poses determine {} of the {} parameters of the model file that more poses identify: use more identification poses",
                self.rank, self.full_rank
            )
        })
    }
}

fn data(machine: &WholeMachine, poses: &[SliderPose]) -> Vec<Measurement> {
    poses
        .iter()
        .map(|p| Measurement {
            joints: p.encoders.map(|e| machine.readings(&e)).unwrap_or_default(),
            q: machine.inputs(&p.sliders),
            obs: Observation::Pose(p.pose),
        })
        .collect()
}

/// Identify `machine` from `ident` (weights: `noise`, or the default when noise-free), validate on
/// `valid` (true poses) and compensate `valid`'s targets, reached on `actual`.
pub fn run_whole_machine(
    machine: &WholeMachine,
    actual: &ActualMachine,
    ident: &[SliderPose],
    valid: &[SliderPose],
    noise: Option<Noise>,
) -> Result<WholeMachineCase, CalibError> {
    let id_data = data(machine, ident);
    let va_data = data(machine, valid);
    let opts = Options {
        noise: noise.unwrap_or_default(),
        free: Some(machine.free.clone()),
        ..Default::default()
    };
    let all: Vec<Vec<f64>> = id_data.iter().chain(&va_data).map(|m| m.q.clone()).collect();
    let full_rank = identify::identifiability_at(&machine.model, &all, &machine.free, &opts.noise, opts.rank_tolerance)?.rank;
    let fit = identify::identify(&machine.model, &id_data, &opts)?;
    let first = identify::identify(
        &machine.model,
        &id_data,
        &Options {
            max_iterations: 1,
            ..opts.clone()
        },
    )?;
    let one_iteration = ErrorStats::of(&validate::pose_errors(&first.model, &va_data)?);
    let nominal_validation = ErrorStats::of(&validate::pose_errors(&machine.model, &va_data)?);
    let validation = ErrorStats::of(&validate::pose_errors(&fit.model, &va_data)?);
    let targets: Vec<Pose> = valid.iter().map(|v| v.target.to_pose()).collect();
    let commands =
        crate::compensate::compensate(&fit.model, &machine.inputs, &targets, None, &|_| {}).map_err(|e| CalibError::Kinematics {
            pose: ident.len() + e.target,
            source: e.source,
        })?;
    let mut comp = CompensationStats::default();
    for (i, (v, q)) in valid.iter().zip(&commands).enumerate() {
        let kin = |source| CalibError::Kinematics {
            pose: ident.len() + i,
            source,
        };
        let (_, reached) = actual.forward(&machine.sliders(q)).map_err(kin)?;
        let p = PlatformPose::from_pose(&machine.model.forward(q).map_err(kin)?);
        let programmed = nalgebra::Vector3::new(p.x - v.target.x, p.y - v.target.y, p.z - v.target.z).norm();
        comp.add(&v.target, &v.pose, &reached, programmed);
    }
    Ok(WholeMachineCase {
        params: machine.model.n_params(),
        free: machine.free.len(),
        observed: machine.model.observed_joints().into_iter().map(|(n, _)| n).collect(),
        rank: fit.identifiability.rank,
        full_rank,
        iterations: fit.iterations.len(),
        converged: fit.converged,
        sigma0: fit.sigma0,
        nominal_validation,
        one_iteration,
        validation,
        compensation: comp,
    })
}
