//! The calibration method of the 3T1R paper (§3–§7) on the preset of
//! [`crate::studies::t3r1_machine`], and its §6 simulation study.
//!
//! # What is identified
//!
//! A [`ChainPair`]: two branched chains (`B1–P` and `B3–P`, or the idle pair `B2–P`, `B4–P`),
//! 30 error coordinates each (`x = [x_1; x_2]`, 60). Per measured pose the sensors give the slider
//! `q_i1`, the upper-parallelogram angle `q_i2` and the platform revolute `q_i4` of both chains
//! ([`PairReading`]); the lower-parallelogram angle `q_i3` is not measured.
//!
//! # `q_i3` from the closure of the current model
//!
//! Eq. (25)–(30) is one equation (the distance `|A1A2|`) in two unknowns; solved with a
//! pseudo-inverse it keeps the distance and leaves the angles wrong. kinecal solves the **full
//! position closure** instead: both chains must put `P` at the same point. Only the `x` and `z`
//! rows depend on the lower angles (they move `A_s` in the `x–z` plane), so
//! `f(q_13, q_23; x) = [x, z](P_1 − P_2) = 0` is a square 2 × 2 system, solved by Newton with the
//! *current* model ([`ChainPair::closure`]). Its solution depends on the parameters; the implicit
//! function theorem gives `dq_3/dx = −(∂f/∂q_3)⁻¹·∂f/∂x` (2 × 60, [`ChainPair::closure_with_jacobian`]),
//! which enters the identification Jacobian. (With the nominal closure the calibration converges to
//! a biased model; with the current closure used as plain data it only creeps.)
//!
//! # Error model: one equation per chain
//!
//! Eq. (21) adds both chains' errors into one 6-vector. The measured pose gives one equation per
//! chain, so the stacked model has 12 rows per pose ([`linearize_pair`]):
//! `e_i = (p_meas − p_i, log(R_meas·R_iᵀ))`, rows `S(p_i)·(J_i (6 × 30 adjoints) + J_{q_i3}·dq_i3/dx)`
//! in the columns of both chains (block diagonal plus the closure coupling), weighted by the
//! measurement noise.
//!
//! # Identification (§5)
//!
//! `AᵀA` of eq. (32) is singular: kinecal identifies the **identifiable subset** (ordered QR in
//! parameter order, [`crate::identifiability::analyze`]) — the other coordinates stay at zero —
//! solves each linearisation by **recursive least squares** ([`rls_sqrt`], square-root
//! information form, equal to batch least squares on that subset to round-off) and updates `T(0) ← T(0)·exp(δt)` (eq. (33)),
//! re-linearising (and re-solving the closure) until `‖X‖` is below a tolerance.
//!
//! # Ranks (20 poses, 60 coordinates; [`ranks`])
//!
//! | | kinecal ([`ErrorModel::LinkDyads`]) | fixed links ([`ErrorModel::FixedLinks`]) | printed chains |
//! |---|---|---|---|
//! | one chain, every `q` measured (/30) | 20 | 18 | 20 |
//! | pair, `q_i3` measured (/60) | 40 | 36 | – |
//! | pair, `q_i3` from the model's closure (/60) | 38 | 34 | – |
//! | literal `A = [J_1, J_2]`, eq. (21) (/60) | 32 | 28 | 34 |
//!
//! * A chain with pose measurements identifies `6 + 2p + 4r'` coordinates, where a parallelogram,
//!   like a revolute, contributes 4: its pivot direction (2) and the link's component
//!   perpendicular to the pivot (length and phase, 2). kinecal's dyads carry the link
//!   (`T_{i2,i3}(0)`, `T_{i3,i4}(0)`), so one chain gives `6 + 2 + 3·4 = 20`. With the links fixed
//!   at `Trans(l)` between the coupled revolutes and the errors on a `T(0)` before every joint, a
//!   parallelogram keeps only 3 (no length error can be represented): `6 + 2 + 3 + 3 + 4 = 18`,
//!   the fixed-link formulation's figure.
//! * The two chains of a pair share no coordinate: 40 (36) with `q_i3` measured.
//! * With `q_i3` from the closure of the model, a change of a lower-parallelogram phase (`13-14.vz`,
//!   `23-24.vz`; fixed links: `13-14.wy`, `23-24.wy`) is absorbed by the recomputed angle: 38 (34).
//! * The paper's 34 (`4r + 2p + 6` with `r = 6`, `p = 2`) is the rank of its literal
//!   `A = [J_1, J_2]` with the printed (frozen) chains, one 6-row block per pose. That matrix
//!   models the sum of both chains' errors, not the two measured equations; kinecal does not use it.
use crate::error::{CalibError, KinError};
use crate::identifiability::{self, Identifiability};
use crate::identify::Linearization;
use crate::measure::Noise;
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use crate::studies::t3r1_machine::{platform_rows, BranchedChain, ChainId, Configuration, ErrorModel, PlatformPose, T3r1};
pub use crate::studies::t3r1_whole::CompensationStats;
use crate::studies::t3r1_whole::{run_whole_machine, EncoderReadings, SliderPose, WholeMachine, WholeMachineCase};
use nalgebra::{DMatrix, DVector, Matrix2, Vector2};
use rayon::prelude::*;
use serde::Serialize;

/// Sensor readings of one pose for a pair of chains: slider, upper angle and platform revolute
/// of each chain (mm, rad).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PairReading {
    /// `q_11`, `q_21` (mm).
    pub sliders: [f64; 2],
    /// `q_12`, `q_22` (rad).
    pub upper: [f64; 2],
    /// `q_14`, `q_24` (rad).
    pub platform: [f64; 2],
}

impl PairReading {
    /// The readings of the chains `ids` (one per side) in a configuration.
    pub fn from_configuration(cfg: &Configuration, ids: [ChainId; 2]) -> Self {
        PairReading {
            sliders: [cfg.sliders[ids[0].index()], cfg.sliders[ids[1].index()]],
            upper: [cfg.upper[ids[0].index()], cfg.upper[ids[1].index()]],
            platform: cfg.platform,
        }
    }
}

/// One measurement: readings, the measured platform pose and (only for the "q_i3 measured"
/// variant and for tests) the lower angles as a sensor would read them.
#[derive(Debug, Clone, PartialEq)]
pub struct PairMeasurement {
    /// Sensor readings.
    pub reading: PairReading,
    /// Measured platform pose.
    pub pose: Pose,
    /// Lower angles `q_13`, `q_23` if measured.
    pub lower: Option<[f64; 2]>,
}

/// Where the lower-parallelogram angles come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum LowerAngles {
    /// From the closure of the current model, with its parameter derivative (kinecal's method).
    Closure,
    /// Measured (sensors on `q_i3`): plain data.
    Measured,
    /// From the closure of the current model, but treated as data (no parameter derivative): an
    /// ablation showing why the derivative is needed (the iteration creeps).
    ClosureAsData,
}

/// Two branched chains, one per side, identified together.
#[derive(Debug, Clone, PartialEq)]
pub struct ChainPair {
    /// Side I and side II chain.
    pub chains: [BranchedChain; 2],
}

impl ChainPair {
    /// The nominal pair `B1`, `B3` (`idle = false`) or `B2`, `B4`.
    pub fn nominal(machine: &T3r1, idle: bool) -> Self {
        let ids = Self::ids(idle);
        ChainPair {
            chains: [machine.chain(ids[0]), machine.chain(ids[1])],
        }
    }

    /// The chain ids of the pair.
    pub fn ids(idle: bool) -> [ChainId; 2] {
        if idle {
            [ChainId::B2, ChainId::B4]
        } else {
            [ChainId::B1, ChainId::B3]
        }
    }

    /// Chain coordinates of chain `k` (0, 1) at a reading and lower angle.
    pub fn inputs(r: &PairReading, k: usize, lower: f64) -> [f64; 4] {
        [r.sliders[k], r.upper[k], lower, r.platform[k]]
    }

    fn closure_residual(&self, r: &PairReading, q3: &[f64; 2]) -> Result<(Vector2<f64>, Matrix2<f64>), KinError> {
        let (g1, j1) = self.chains[0].joint_jacobian(&Self::inputs(r, 0, q3[0]))?;
        let (g2, j2) = self.chains[1].joint_jacobian(&Self::inputs(r, 1, q3[1]))?;
        let d = g1.translation.vector - g2.translation.vector;
        let c1 = platform_rows(&g1, &j1.column(2).into_owned());
        let c2 = platform_rows(&g2, &j2.column(2).into_owned());
        let jq = Matrix2::new(c1.x, -c2.x, c1.z, -c2.z);
        Ok((Vector2::new(d.x, d.z), jq))
    }

    /// The lower angles `q_13`, `q_23` that close the current model at reading `r`: Newton on
    /// `[x, z](P_1 − P_2) = 0` from `seed`.
    pub fn closure(&self, r: &PairReading, seed: [f64; 2]) -> Result<[f64; 2], KinError> {
        let mut q = seed;
        let mut res = f64::INFINITY;
        for _ in 0..50 {
            let (f, jq) = self.closure_residual(r, &q)?;
            res = f.norm();
            let step = jq.lu().solve(&f).ok_or_else(|| KinError::Singular {
                what: "lower-parallelogram closure".into(),
                condition: f64::INFINITY,
            })?;
            q[0] -= step[0];
            q[1] -= step[1];
            if step.norm() < 1e-14 || res < 1e-12 {
                let (f, _) = self.closure_residual(r, &q)?;
                if f.norm() < 1e-9 {
                    return Ok(q);
                }
            }
        }
        Err(KinError::NoConvergence {
            what: "lower-parallelogram closure".into(),
            iterations: 50,
            residual: res,
        })
    }

    /// [`ChainPair::closure`] and its derivative `dq_3/dx` (2 × 60) by the implicit function
    /// theorem: `−(∂f/∂q_3)⁻¹·∂f/∂x`.
    pub fn closure_with_jacobian(&self, r: &PairReading, seed: [f64; 2]) -> Result<([f64; 2], DMatrix<f64>), KinError> {
        self.closure_with_jacobian_of(r, seed, ErrorModel::LinkDyads)
    }

    /// [`ChainPair::closure_with_jacobian`] for the coordinates of `model`.
    pub fn closure_with_jacobian_of(
        &self,
        r: &PairReading,
        seed: [f64; 2],
        model: ErrorModel,
    ) -> Result<([f64; 2], DMatrix<f64>), KinError> {
        let q = self.closure(r, seed)?;
        let (_, jq) = self.closure_residual(r, &q)?;
        let mut fx = DMatrix::zeros(2, 60);
        for k in 0..2 {
            let (g, j) = self.chains[k].identification_jacobian(&Self::inputs(r, k, q[k]), model)?;
            let sign = if k == 0 { 1.0 } else { -1.0 };
            for c in 0..30 {
                let rows = platform_rows(&g, &j.column(c).into_owned());
                fx[(0, 30 * k + c)] = sign * rows.x;
                fx[(1, 30 * k + c)] = sign * rows.z;
            }
        }
        let inv = jq.try_inverse().ok_or_else(|| KinError::Singular {
            what: "lower-parallelogram closure".into(),
            condition: f64::INFINITY,
        })?;
        let inv = DMatrix::from_iterator(2, 2, inv.iter().copied());
        Ok((q, -(inv * fx)))
    }

    /// Platform poses predicted by both chains at reading `r` (lower angles from the closure).
    pub fn predict(&self, r: &PairReading, seed: [f64; 2]) -> Result<[Pose; 2], KinError> {
        let q = self.closure(r, seed)?;
        Ok([
            self.chains[0].forward(&Self::inputs(r, 0, q[0]))?,
            self.chains[1].forward(&Self::inputs(r, 1, q[1]))?,
        ])
    }

    /// `T(0) ← T(0)·exp(δt)` on both chains (60 coordinates).
    pub fn retract(&mut self, delta: &DVector<f64>) {
        self.chains[0].retract(&delta.rows(0, 30).into_owned());
        self.chains[1].retract(&delta.rows(30, 30).into_owned());
    }

    /// Parameter names (`B-11.vx`, …, `24-P.wz`).
    pub fn param_names(&self) -> Vec<String> {
        self.chains.iter().flat_map(|c| c.params().into_iter().map(|p| p.name)).collect()
    }

    /// Nominal lower angles, the Newton seed of the closure.
    pub fn seed() -> [f64; 2] {
        [std::f64::consts::FRAC_PI_3, 2.0 * std::f64::consts::FRAC_PI_3]
    }
}

/// The stacked, weighted linearisation of a pair at `data`: 12 rows per pose (one 6-row equation
/// per chain), 60 columns; with [`LowerAngles::Closure`] the closure derivative couples the chains.
pub fn linearize_pair(pair: &ChainPair, data: &[PairMeasurement], noise: &Noise, lower: LowerAngles) -> Result<Linearization, CalibError> {
    linearize_pair_of(pair, data, noise, lower, ErrorModel::LinkDyads)
}

/// [`linearize_pair`] in the coordinates of `model`.
pub fn linearize_pair_of(
    pair: &ChainPair,
    data: &[PairMeasurement],
    noise: &Noise,
    lower: LowerAngles,
    model: ErrorModel,
) -> Result<Linearization, CalibError> {
    let w = [
        1.0 / noise.position,
        1.0 / noise.position,
        1.0 / noise.position,
        1.0 / noise.orientation,
        1.0 / noise.orientation,
        1.0 / noise.orientation,
    ];
    let blocks: Vec<(DMatrix<f64>, DVector<f64>)> = data
        .par_iter()
        .enumerate()
        .map(|(i, m)| {
            let kin = |source| CalibError::Kinematics { pose: i, source };
            let (q3, dq3) = match lower {
                LowerAngles::Closure => {
                    let (q, d) = pair.closure_with_jacobian_of(&m.reading, ChainPair::seed(), model).map_err(kin)?;
                    (q, Some(d))
                }
                LowerAngles::ClosureAsData => (pair.closure(&m.reading, ChainPair::seed()).map_err(kin)?, None),
                LowerAngles::Measured => (
                    m.lower
                        .ok_or_else(|| CalibError::InvalidOption(format!("pose {i}: lower angles not measured")))?,
                    None,
                ),
            };
            let mut a = DMatrix::zeros(12, 60);
            let mut r = DVector::zeros(12);
            for k in 0..2 {
                let q = ChainPair::inputs(&m.reading, k, q3[k]);
                let (g, j) = pair.chains[k].identification_jacobian(&q, model).map_err(kin)?;
                let s = se3::spatial_to_pose_error(&g.translation.vector);
                let e = se3::pose_error(&m.pose, &g);
                let jk = s * j;
                for row in 0..6 {
                    r[6 * k + row] = e[row] * w[row];
                    for c in 0..30 {
                        a[(6 * k + row, 30 * k + c)] = jk[(row, c)] * w[row];
                    }
                }
                if let Some(d) = &dq3 {
                    let (_, jq) = pair.chains[k].joint_jacobian(&q).map_err(kin)?;
                    let col = s * jq.column(2);
                    for row in 0..6 {
                        for c in 0..60 {
                            a[(6 * k + row, c)] += col[row] * d[(k, c)] * w[row];
                        }
                    }
                }
            }
            Ok((a, r))
        })
        .collect::<Result<_, CalibError>>()?;
    let rows = 12 * blocks.len();
    let mut jacobian = DMatrix::zeros(rows, 60);
    let mut residual = DVector::zeros(rows);
    for (i, (a, r)) in blocks.iter().enumerate() {
        jacobian.view_mut((12 * i, 0), (12, 60)).copy_from(a);
        residual.rows_mut(12 * i, 12).copy_from(r);
    }
    Ok(Linearization {
        jacobian,
        residual,
        offsets: (0..blocks.len()).map(|i| 12 * i).collect(),
        angular_rows: (0..rows).map(|k| k % 6 >= 3).collect(),
    })
}

/// Recursive least squares pose block after pose block on the columns `cols`: the core's
/// square-root information form [`crate::identify::rls_solve`].
pub fn rls_sqrt(lin: &Linearization, cols: &[usize]) -> Result<DVector<f64>, CalibError> {
    crate::identify::rls_solve(lin, cols)
}

/// Options of [`identify_pair`].
#[derive(Debug, Clone, PartialEq)]
pub struct PairOptions {
    /// Noise standard deviations (row weights).
    pub noise: Noise,
    /// Source of the lower angles.
    pub lower: LowerAngles,
    /// Maximum number of linearise–solve–update iterations.
    pub max_iterations: usize,
    /// Stop when `‖X‖` (mm and rad together) falls below this.
    pub x_tolerance: f64,
    /// Relative rank tolerance.
    pub rank_tolerance: f64,
}

impl Default for PairOptions {
    fn default() -> Self {
        PairOptions {
            noise: Noise::default(),
            lower: LowerAngles::Closure,
            max_iterations: 40,
            x_tolerance: 1e-9,
            rank_tolerance: identifiability::DEFAULT_RANK_TOLERANCE,
        }
    }
}

/// One iteration of [`identify_pair`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairIteration {
    /// `‖X‖` of the step (mm and rad together).
    pub x_norm: f64,
    /// Weighted cost `½|r|²` after the update.
    pub cost: f64,
}

/// Result of [`identify_pair`].
#[derive(Debug, Clone)]
pub struct PairIdentification {
    /// Calibrated pair after the first iteration (the paper's one-shot result).
    pub first: ChainPair,
    /// Calibrated pair at the end.
    pub pair: ChainPair,
    /// Identifiability at the starting model.
    pub identifiability: Identifiability,
    /// Iteration history.
    pub history: Vec<PairIteration>,
    /// Whether `‖X‖` reached the tolerance.
    pub converged: bool,
}

/// Shortest fraction of a recursive least-squares step [`identify_pair`] tries.
const MIN_STEP_FRACTION: f64 = 1.0 / 1024.0;

/// Identify a pair from `data`: identifiable subset, RLS per linearisation, `T(0) ← T(0)·exp(δt)`,
/// iterated until `‖X‖ < x_tolerance` (or, at round-off level, neither the cost nor `‖X‖`
/// decreases twice in a row). With noise the iteration converges linearly (the residual is not
/// zero), noise-free quadratically.
pub fn identify_pair(initial: &ChainPair, data: &[PairMeasurement], opts: &PairOptions) -> Result<PairIdentification, CalibError> {
    if !(opts.noise.position > 0.0 && opts.noise.orientation > 0.0) {
        return Err(CalibError::InvalidOption("noise standard deviations must be positive".into()));
    }
    let mut pair = initial.clone();
    let mut lin = linearize_pair(&pair, data, &opts.noise, opts.lower)?;
    let all: Vec<usize> = (0..60).collect();
    let ident = identifiability::analyze(&lin.jacobian, &all, opts.rank_tolerance);
    let cols = ident.identifiable.clone();
    if lin.residual.len() <= cols.len() {
        return Err(CalibError::TooFewMeasurements {
            poses: data.len(),
            rows: lin.residual.len(),
            params: cols.len(),
            needed: cols.len() / 12 + 1,
        });
    }
    let mut history = Vec::new();
    let mut first = None;
    let mut converged = false;
    let mut stalls = 0;
    for _ in 0..opts.max_iterations.max(1) {
        let cost0 = 0.5 * lin.residual.norm_squared();
        let full = rls_sqrt(&lin, &cols)?;
        // The recursive least-squares step, halved while it raises the cost or leaves a pose
        // where the lower closure no longer assembles (few poses: weakly determined directions
        // overshoot); the full step whenever it helps, as in the paper.
        let mut alpha = 1.0;
        let (step, trial, trial_lin) = loop {
            let step = &full * alpha;
            let mut trial = pair.clone();
            trial.retract(&step);
            match linearize_pair(&trial, data, &opts.noise, opts.lower) {
                Ok(l) if 0.5 * l.residual.norm_squared() <= cost0 * (1.0 + 1e-9) || alpha < MIN_STEP_FRACTION => break (step, trial, l),
                Ok(_) | Err(CalibError::Kinematics { .. }) if alpha >= MIN_STEP_FRACTION => alpha *= 0.5,
                Ok(l) => break (step, trial, l),
                Err(e) => return Err(e),
            }
        };
        let x_norm = step.norm();
        let cost = 0.5 * trial_lin.residual.norm_squared();
        if cost > cost0 * (1.0 + 1e-9) {
            // Not even a short step lowers the cost: stop, not converged.
            break;
        }
        history.push(PairIteration { x_norm, cost });
        pair = trial;
        lin = trial_lin;
        if first.is_none() {
            first = Some(pair.clone());
        }
        if x_norm < opts.x_tolerance {
            converged = true;
            break;
        }
        // Round-off level: neither the cost nor ‖X‖ decreases any more.
        let prev_x = history.len().checked_sub(2).map(|i| history[i].x_norm).unwrap_or(f64::INFINITY);
        if cost >= cost0 * (1.0 - 1e-12) && x_norm >= prev_x {
            stalls += 1;
            if stalls >= 2 {
                converged = true;
                break;
            }
        } else {
            stalls = 0;
        }
    }
    Ok(PairIdentification {
        first: first.unwrap_or_else(|| pair.clone()),
        pair,
        identifiability: ident,
        history,
        converged,
    })
}

/// Ranks of the identification Jacobian of one error model over a data set.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModelRanks {
    /// Error model.
    pub model: ErrorModel,
    /// Chain `B1` alone, every coordinate measured (of 30).
    pub one_chain: usize,
    /// The pair with `q_i3` measured (of 60).
    pub pair_measured: usize,
    /// The pair with `q_i3` from the model's closure (of 60).
    pub pair_closure: usize,
    /// The paper's literal `A = [J_1, J_2]`, one 6-row block per pose (of 60).
    pub paper_literal: usize,
    /// Coordinates that the closure makes redundant (identifiable with `q_i3` measured, not with
    /// the closure).
    pub lost_to_closure: Vec<String>,
}

/// Ranks of both error models.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ranks {
    /// Poses used.
    pub poses: usize,
    /// kinecal's model ([`ErrorModel::LinkDyads`]).
    pub link_dyads: ModelRanks,
    /// The fixed-link model ([`ErrorModel::FixedLinks`]).
    pub fixed_links: ModelRanks,
    /// The printed chains of §6 (counter-rotations frozen at `α`, `β`; ordinary 1P3R serial
    /// chains): one chain (of 30).
    pub printed_one_chain: usize,
    /// The printed chains: the paper's literal `A = [J_1, J_2]` (of 60) — the paper's 34.
    pub printed_literal: usize,
}

/// The ranks of [`Ranks`] for `pair` at `data` (which must carry the lower angles).
///
/// The printed chains are evaluated with the pair's own serial chains, the counter-rotation joints
/// frozen at `−α` (upper) and `−β`, `−(π − β)` (lower, sides I and II) of `geometry`, and the error
/// coordinates on the dyads before each joint.
pub fn ranks(
    pair: &ChainPair,
    data: &[PairMeasurement],
    geometry: &crate::studies::t3r1_machine::Geometry,
    tol: f64,
) -> Result<Ranks, CalibError> {
    let n = data.len();
    let mut one = DMatrix::zeros(6 * n, 30);
    let mut lit = DMatrix::zeros(6 * n, 60);
    let frozen_lower = [geometry.beta(), std::f64::consts::PI - geometry.beta()];
    for (i, m) in data.iter().enumerate() {
        let lower = m
            .lower
            .ok_or_else(|| CalibError::InvalidOption(format!("pose {i}: lower angles not measured")))?;
        for k in 0..2 {
            let q = ChainPair::inputs(&m.reading, k, lower[k]);
            let q6 = [q[0], q[1], -geometry.alpha(), q[2], -frozen_lower[k], q[3]];
            let (_, j42) = pair.chains[k]
                .serial()
                .forward_with_jacobian(&q6)
                .map_err(|source| CalibError::Kinematics { pose: i, source })?;
            for (kk, d) in [0usize, 1, 3, 5, 6].iter().enumerate() {
                for r in 0..6 {
                    for c in 0..6 {
                        lit[(6 * i + r, 30 * k + 6 * kk + c)] = j42[(r, 6 * d + c)];
                        if k == 0 {
                            one[(6 * i + r, 6 * kk + c)] = j42[(r, 6 * d + c)];
                        }
                    }
                }
            }
        }
    }
    let all30: Vec<usize> = (0..30).collect();
    let all60: Vec<usize> = (0..60).collect();
    Ok(Ranks {
        poses: data.len(),
        link_dyads: model_ranks(pair, data, tol, ErrorModel::LinkDyads)?,
        fixed_links: model_ranks(pair, data, tol, ErrorModel::FixedLinks)?,
        printed_one_chain: identifiability::analyze(&one, &all30, tol).rank,
        printed_literal: identifiability::analyze(&lit, &all60, tol).rank,
    })
}

fn model_ranks(pair: &ChainPair, data: &[PairMeasurement], tol: f64, model: ErrorModel) -> Result<ModelRanks, CalibError> {
    let noise = Noise {
        position: 1.0,
        orientation: 1.0,
        ..Noise::default()
    };
    let closure = linearize_pair_of(pair, data, &noise, LowerAngles::Closure, model)?;
    let measured = linearize_pair_of(pair, data, &noise, LowerAngles::Measured, model)?;
    let all60: Vec<usize> = (0..60).collect();
    let ic = identifiability::analyze(&closure.jacobian, &all60, tol);
    let im = identifiability::analyze(&measured.jacobian, &all60, tol);
    let n = data.len();
    let mut one = DMatrix::zeros(6 * n, 30);
    let mut lit = DMatrix::zeros(6 * n, 60);
    for (i, m) in data.iter().enumerate() {
        let lower = m
            .lower
            .ok_or_else(|| CalibError::InvalidOption(format!("pose {i}: lower angles not measured")))?;
        for (k, (chain, q3)) in pair.chains.iter().zip(lower.iter()).enumerate() {
            let (_, j) = chain
                .identification_jacobian(&ChainPair::inputs(&m.reading, k, *q3), model)
                .map_err(|source| CalibError::Kinematics { pose: i, source })?;
            for r in 0..6 {
                for c in 0..30 {
                    if k == 0 {
                        one[(6 * i + r, c)] = j[(r, c)];
                    }
                    lit[(6 * i + r, 30 * k + c)] = j[(r, c)];
                }
            }
        }
    }
    let all30: Vec<usize> = (0..30).collect();
    let i1 = identifiability::analyze(&one, &all30, tol);
    let il = identifiability::analyze(&lit, &all60, tol);
    let names = pair.param_names();
    let lost_to_closure = im
        .identifiable
        .iter()
        .filter(|c| !ic.identifiable.contains(c))
        .map(|&c| names[c].clone())
        .collect();
    Ok(ModelRanks {
        model,
        one_chain: i1.rank,
        pair_measured: im.rank,
        pair_closure: ic.rank,
        paper_literal: il.rank,
        lost_to_closure,
    })
}

/// Calibrated inverse kinematics (§7, Fig. 6): slider commands for `target` from the four
/// calibrated chains (`main` = `B1`, `B3`; `idle` = `B2`, `B4`), each solved for `(x, y, z, yaw)`
/// from the nominal inverse kinematics; returns the slider commands and `T_cp`, the nominal
/// forward kinematics of those commands (what a controller with nominal kinematics is sent).
pub fn compensate(main: &ChainPair, idle: &ChainPair, nominal: &T3r1, target: &PlatformPose) -> Result<([f64; 4], PlatformPose), KinError> {
    let start = nominal.inverse(target)?;
    let mut sliders = [0.0; 4];
    for (pair, is_idle) in [(main, false), (idle, true)] {
        let ids = ChainPair::ids(is_idle);
        for k in 0..2 {
            let q = pair.chains[k].inverse_platform(target, &start.chain_inputs(ids[k]))?;
            sliders[ids[k].index()] = q[0];
        }
    }
    let cfg = nominal.forward(&sliders)?;
    let t_cp = PlatformPose::from_pose(&nominal.pose(&cfg)?);
    Ok((sliders, t_cp))
}

/// The lower angles by the paper's eq. (25)–(30): the one distance equation
/// `|A_1A_2| = a` solved for `(q_13, q_23)` with the 1 × 2 pseudo-inverse, from `seed`. Kept to show
/// why kinecal does not use it: it satisfies the distance and leaves the angles wrong.
pub fn lower_angles_eq25(pair: &ChainPair, r: &PairReading, a: f64, seed: [f64; 2]) -> Result<[f64; 2], KinError> {
    let point =
        |k: usize, q3: f64| -> Result<nalgebra::Vector3<f64>, KinError> { Ok(pair.chains[k].points(&ChainPair::inputs(r, k, q3))?.1) };
    let mut q = seed;
    let h = 1e-7;
    for _ in 0..100 {
        let (a1, a2) = (point(0, q[0])?, point(1, q[1])?);
        let d = a2 - a1;
        let dist = d.norm();
        let dd = a - dist;
        if dd.abs() < 1e-12 {
            break;
        }
        let u = d / dist;
        let da1 = (point(0, q[0] + h)? - point(0, q[0] - h)?) / (2.0 * h);
        let da2 = (point(1, q[1] + h)? - point(1, q[1] - h)?) / (2.0 * h);
        let j = nalgebra::RowVector2::new(-u.dot(&da1), u.dot(&da2));
        let n2 = j.norm_squared();
        if n2 == 0.0 {
            return Err(KinError::Singular {
                what: "eq. (29)".into(),
                condition: f64::INFINITY,
            });
        }
        q[0] += j[0] * dd / n2;
        q[1] += j[1] * dd / n2;
    }
    Ok(q)
}

/// Noise of the simulated measurements.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct StudyNoise {
    /// Pose position noise per axis (mm).
    pub position: f64,
    /// Pose orientation noise per axis (rad).
    pub orientation: f64,
    /// Angle-encoder noise (rad) on the upper and platform angles (sliders are exact).
    pub encoder: f64,
}

impl Default for StudyNoise {
    /// 20 µm, 0.02°, encoders 0.01°.
    fn default() -> Self {
        StudyNoise {
            position: 0.020,
            orientation: 0.02f64.to_radians(),
            encoder: 0.01f64.to_radians(),
        }
    }
}

/// Configuration of the §6 study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyConfig {
    /// Seed of every random draw.
    pub seed: u64,
    /// Identification poses.
    pub identification_poses: usize,
    /// Validation poses.
    pub validation_poses: usize,
    /// Preset errors of the simulated machine.
    pub errors: crate::studies::t3r1_machine::PresetErrors,
    /// Workspace the poses are drawn from.
    pub workspace: crate::studies::t3r1_machine::Workspace,
    /// Noise of the noisy run (the weights of its identification are the same values).
    pub noise: StudyNoise,
    /// The whole machine's model file the same data are also identified with (a path, or the
    /// built-in `t3r1`; [`crate::studies::t3r1_whole`]).
    pub model: String,
}

impl Default for StudyConfig {
    fn default() -> Self {
        StudyConfig {
            seed: 2020,
            identification_poses: 20,
            validation_poses: 20,
            errors: Default::default(),
            workspace: Default::default(),
            noise: StudyNoise::default(),
            model: "t3r1".into(),
        }
    }
}

/// Pose-error statistics of a chain pair, the worse of its two chains per pose (mm, degrees;
/// the general statistics are [`crate::validate::ErrorStats`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Default)]
pub struct PairErrorStats {
    /// Mean position error (mm).
    pub mean_position_mm: f64,
    /// Largest position error (mm).
    pub max_position_mm: f64,
    /// Mean orientation error (deg).
    pub mean_orientation_deg: f64,
    /// Largest orientation error (deg).
    pub max_orientation_deg: f64,
}

impl PairErrorStats {
    fn from(errs: &[(f64, f64)]) -> Self {
        let n = errs.len().max(1) as f64;
        PairErrorStats {
            mean_position_mm: errs.iter().map(|e| e.0).sum::<f64>() / n,
            max_position_mm: errs.iter().map(|e| e.0).fold(0.0, f64::max),
            mean_orientation_deg: errs.iter().map(|e| e.1).sum::<f64>() / n * 180.0 / std::f64::consts::PI,
            max_orientation_deg: errs.iter().map(|e| e.1).fold(0.0, f64::max) * 180.0 / std::f64::consts::PI,
        }
    }
}

/// Errors of a pair's predictions (the worse of its two chains per pose) against `data`.
pub fn pair_errors(pair: &ChainPair, data: &[PairMeasurement]) -> Result<PairErrorStats, CalibError> {
    let errs = data
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let p = pair
                .predict(&m.reading, ChainPair::seed())
                .map_err(|source| CalibError::Kinematics { pose: i, source })?;
            let (mut dp, mut dw) = (0.0f64, 0.0f64);
            for g in &p {
                let e = se3::pose_error(&m.pose, g);
                dp = dp.max(se3::lin(&e).norm());
                dw = dw.max(se3::ang(&e).norm());
            }
            Ok((dp, dw))
        })
        .collect::<Result<Vec<_>, CalibError>>()?;
    Ok(PairErrorStats::from(&errs))
}

/// The idle-pair cross-validation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CrossValidation {
    /// Validation errors of the calibrated idle pair.
    pub idle_validation: PairErrorStats,
    /// Largest position difference of the two calibrated pairs' predictions (mm).
    pub agreement_position_mm: f64,
    /// Largest orientation difference (deg).
    pub agreement_orientation_deg: f64,
}

/// One variant of the lower-angle source in the noise-free ablation.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Ablation {
    /// What was done.
    pub variant: String,
    /// Iterations run.
    pub iterations: usize,
    /// Validation errors at the end.
    pub validation: PairErrorStats,
    /// `‖X‖` of the last iteration.
    pub last_x_norm: f64,
}

/// One case (noise-free or noisy) of the study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyCase {
    /// Noise, if any.
    pub noise: Option<StudyNoise>,
    /// Identifiable coordinates (of 60).
    pub identified: usize,
    /// Errors of the nominal model: identification and validation poses.
    pub nominal: [PairErrorStats; 2],
    /// Errors after one iteration (the paper's result).
    pub one_iteration: [PairErrorStats; 2],
    /// Errors after convergence.
    pub converged: [PairErrorStats; 2],
    /// `‖X‖` per iteration.
    pub x_norms: Vec<f64>,
    /// Whether `‖X‖` reached the tolerance.
    pub reached_tolerance: bool,
    /// Idle-pair cross-validation.
    pub cross_validation: CrossValidation,
    /// §7 compensation on the validation targets.
    pub compensation: CompensationStats,
    /// Other sources of the lower angles (noise-free case only; empty otherwise).
    pub ablations: Vec<Ablation>,
    /// The same data identified with the whole machine's model file from the sliders alone
    /// (`None` when that identification failed: [`StudyCase::whole_machine_error`]).
    pub whole_machine: Option<WholeMachineCase>,
    /// Why the model file's identification failed, if it did (e.g. fewer rows than its
    /// identifiable parameters).
    pub whole_machine_error: Option<String>,
}

impl StudyCase {
    /// Why the model file's identification of this case cannot be trusted, if it cannot.
    pub fn whole_machine_failure(&self) -> Option<String> {
        match (&self.whole_machine, &self.whole_machine_error) {
            (_, Some(e)) => Some(format!("the model file's identification failed: {e}")),
            (Some(w), None) => w.failure(),
            (None, None) => None,
        }
    }
}

impl StudyCase {
    /// Why this case's identification cannot be trusted, if it cannot: `‖X‖` never reached the
    /// tolerance (not converged), or the iterations ended with a larger identification-set error
    /// than the first one reached (diverged into a wrong solution).
    pub fn failure(&self) -> Option<String> {
        let (first, last) = (&self.one_iteration[0], &self.converged[0]);
        if last.max_position_mm > first.max_position_mm * 1.0001 || last.max_orientation_deg > first.max_orientation_deg * 1.0001 {
            return Some(format!(
                "diverged: the identification-set error grew from {:.4} mm / {:.4} deg after one iteration to {:.4} mm / {:.4} deg after {} (too few poses for {} identified coordinates, or noise that the data cannot average out)",
                first.max_position_mm,
                first.max_orientation_deg,
                last.max_position_mm,
                last.max_orientation_deg,
                self.x_norms.len(),
                self.identified
            ));
        }
        if !self.reached_tolerance {
            return Some(format!(
                "not converged: ||X|| is still {:.2e} after {} iterations",
                self.x_norms.last().copied().unwrap_or(f64::NAN),
                self.x_norms.len()
            ));
        }
        None
    }
}

/// Checks of the lower-angle estimate on the actual machine (true model, true readings).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LowerAngleCheck {
    /// Largest error of the closure estimate (deg).
    pub closure_max_error_deg: f64,
    /// Largest error of eq. (25)–(30) with the pseudo-inverse (deg).
    pub eq25_max_error_deg: f64,
    /// Largest `| |A1A2| − a |` left by eq. (25)–(30) (mm).
    pub eq25_distance_residual_mm: f64,
}

/// The whole §6 study.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StudyReport {
    /// Configuration.
    pub config: StudyConfig,
    /// Ranks over the identification poses (nominal model).
    pub ranks: Ranks,
    /// Lower-angle estimate on the actual machine.
    pub lower_angles: LowerAngleCheck,
    /// Largest condition number of `d(x, y, z, (a/2)·yaw)/d(sliders)` (all rows in mm) over the
    /// drawn poses.
    pub worst_actuator_condition: f64,
    /// Noise-free case.
    pub noise_free: StudyCase,
    /// Noisy case.
    pub noisy: StudyCase,
    /// What more poses identify: the pair's rank with closure-computed lower angles over the
    /// identification and validation poses together, and the fewest of them (in drawing order)
    /// that reach it.
    pub full_rank: FullRank,
}

/// The rank of the pair's identification Jacobian (lower angles from the closure) over every drawn
/// pose, and how many poses reach it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FullRank {
    /// Rank over every drawn pose (identification and validation).
    pub rank: usize,
    /// Fewest poses, in drawing order, with that rank.
    pub poses: usize,
}

impl StudyReport {
    /// Why a failed run failed, when the identification poses were too few to determine every
    /// coordinate that more poses determine.
    pub fn too_few_poses(&self) -> Option<String> {
        (self.noise_free.identified < self.full_rank.rank).then(|| {
            format!(
                "{} identification poses determine {} of the {} coordinates that more poses identify (all {} from {} poses of this draw): use more identification poses",
                self.config.identification_poses, self.noise_free.identified, self.full_rank.rank, self.full_rank.rank, self.full_rank.poses
            )
        })
    }
}

/// [`FullRank`] of `data` (noise-free readings of the drawn poses).
fn full_rank(pair: &ChainPair, data: &[PairMeasurement], tol: f64) -> Result<FullRank, CalibError> {
    let noise = Noise {
        position: 1.0,
        orientation: 1.0,
        ..Noise::default()
    };
    let lin = linearize_pair(pair, data, &noise, LowerAngles::Closure)?;
    let all60: Vec<usize> = (0..60).collect();
    let rank = identifiability::analyze(&lin.jacobian, &all60, tol).rank;
    let poses = (1..=data.len())
        .find(|&k| identifiability::analyze(&lin.jacobian.rows(0, 12 * k).into_owned(), &all60, tol).rank == rank)
        .unwrap_or(data.len());
    Ok(FullRank { rank, poses })
}

struct SimPose {
    target: PlatformPose,
    truth: Configuration,
    pose: Pose,
}

fn measurements(
    sims: &[SimPose],
    ids: [ChainId; 2],
    noise: Option<&StudyNoise>,
    rng: &mut rand_chacha::ChaCha8Rng,
) -> Vec<PairMeasurement> {
    use rand_distr::{Distribution, Normal};
    sims.iter()
        .map(|s| {
            let mut cfg = s.truth.clone();
            let mut pose = s.pose;
            if let Some(n) = noise {
                let ne = Normal::new(0.0, n.encoder).expect("finite σ");
                let np = Normal::new(0.0, n.position).expect("finite σ");
                let nw = Normal::new(0.0, n.orientation).expect("finite σ");
                for v in cfg.upper.iter_mut().chain(cfg.platform.iter_mut()) {
                    *v += ne.sample(rng);
                }
                let dp = nalgebra::Vector3::new(np.sample(rng), np.sample(rng), np.sample(rng));
                let dw = nalgebra::Vector3::new(nw.sample(rng), nw.sample(rng), nw.sample(rng));
                pose = Pose::from_parts(
                    nalgebra::Translation3::from(pose.translation.vector + dp),
                    se3::so3_exp(&dw) * pose.rotation,
                );
            }
            PairMeasurement {
                reading: PairReading::from_configuration(&cfg, ids),
                pose,
                lower: Some(s.truth.lower),
            }
        })
        .collect()
}

#[allow(clippy::too_many_arguments)]
fn run_case(
    whole: &WholeMachine,
    nominal: &T3r1,
    actual: &crate::studies::t3r1_machine::ActualMachine,
    ident: &[SimPose],
    valid: &[SimPose],
    noise: Option<StudyNoise>,
    seed: u64,
) -> Result<StudyCase, CalibError> {
    use rand::SeedableRng;
    let rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let opts = PairOptions {
        noise: noise
            .map(|n| Noise {
                position: n.position,
                orientation: n.orientation,
                ..Noise::default()
            })
            .unwrap_or_default(),
        ..Default::default()
    };
    let mut results = Vec::new();
    for idle in [false, true] {
        let ids = ChainPair::ids(idle);
        // One noisy measurement per pose for both pairs: the same generator state draws the same
        // tracker noise and the same encoder noise of every physical sensor (4 upper, 2 platform).
        let id_data = measurements(ident, ids, noise.as_ref(), &mut rng.clone());
        let va_data = measurements(valid, ids, None, &mut rng.clone());
        let start = ChainPair::nominal(nominal, idle);
        let result = identify_pair(&start, &id_data, &opts)?;
        results.push((start, result, id_data, va_data));
    }
    let (start, main, id_data, va_data) = &results[0];
    let (_, idle, _, idle_va) = &results[1];
    let nominal_err = [pair_errors(start, id_data)?, pair_errors(start, va_data)?];
    let first = [pair_errors(&main.first, id_data)?, pair_errors(&main.first, va_data)?];
    let last = [pair_errors(&main.pair, id_data)?, pair_errors(&main.pair, va_data)?];
    // Cross-validation: the two calibrated pairs on the validation poses.
    let (mut ap, mut aw) = (0.0f64, 0.0f64);
    for (i, (m, mi)) in va_data.iter().zip(idle_va.iter()).enumerate() {
        let kin = |source| CalibError::Kinematics { pose: i, source };
        let a = main.pair.predict(&m.reading, ChainPair::seed()).map_err(kin)?;
        let b = idle.pair.predict(&mi.reading, ChainPair::seed()).map_err(kin)?;
        let e = se3::pose_error(&a[0], &b[0]);
        ap = ap.max(se3::lin(&e).norm());
        aw = aw.max(se3::ang(&e).norm());
    }
    let cross_validation = CrossValidation {
        idle_validation: pair_errors(&idle.pair, idle_va)?,
        agreement_position_mm: ap,
        agreement_orientation_deg: aw.to_degrees(),
    };
    // Compensation.
    let mut comp = CompensationStats::default();
    for (i, s) in valid.iter().enumerate() {
        let kin = |source| CalibError::Kinematics { pose: i, source };
        let (sliders, t_cp) = compensate(&main.pair, &idle.pair, nominal, &s.target).map_err(kin)?;
        let (_, reached) = actual.forward(&sliders).map_err(kin)?;
        let dprog = nalgebra::Vector3::new(t_cp.x - s.target.x, t_cp.y - s.target.y, t_cp.z - s.target.z).norm();
        comp.add(&s.target, &s.pose, &reached, dprog);
    }
    // The same tracker and encoder readings (the main and the idle pair's data share them).
    let idle_id = &results[1].2;
    let ident_poses: Vec<SliderPose> = ident
        .iter()
        .zip(id_data.iter().zip(idle_id))
        .map(|(s, (m, mi))| SliderPose {
            sliders: s.truth.sliders,
            pose: m.pose,
            target: s.target,
            encoders: Some(EncoderReadings {
                upper: [m.reading.upper[0], mi.reading.upper[0], m.reading.upper[1], mi.reading.upper[1]],
                platform: m.reading.platform,
            }),
        })
        .collect();
    let valid_poses: Vec<SliderPose> = valid
        .iter()
        .zip(va_data)
        .map(|(s, m)| SliderPose {
            sliders: s.truth.sliders,
            pose: m.pose,
            target: s.target,
            encoders: None,
        })
        .collect();
    let (whole_machine, whole_machine_error) = match run_whole_machine(
        whole,
        actual,
        &ident_poses,
        &valid_poses,
        noise.map(|n| Noise {
            joint_angle: n.encoder,
            ..opts.noise
        }),
    ) {
        Ok(w) => (Some(w), None),
        Err(e) => (None, Some(e.to_string())),
    };
    let mut ablations = Vec::new();
    if noise.is_none() {
        let mut nominal_closure = id_data.clone();
        for (i, m) in nominal_closure.iter_mut().enumerate() {
            m.lower = Some(
                start
                    .closure(&m.reading, ChainPair::seed())
                    .map_err(|source| CalibError::Kinematics { pose: i, source })?,
            );
        }
        let variants = [
            (
                "q_i3 measured (sensor on the lower parallelogram)",
                LowerAngles::Measured,
                id_data.clone(),
            ),
            (
                "q_i3 from the nominal model's closure, as data",
                LowerAngles::Measured,
                nominal_closure,
            ),
            (
                "q_i3 from the current closure, as data (no derivative)",
                LowerAngles::ClosureAsData,
                id_data.clone(),
            ),
        ];
        for (name, lower, data) in variants {
            let r = identify_pair(start, &data, &PairOptions { lower, ..opts.clone() })?;
            ablations.push(Ablation {
                variant: name.to_string(),
                iterations: r.history.len(),
                validation: pair_errors(&r.pair, va_data)?,
                last_x_norm: r.history.last().map(|h| h.x_norm).unwrap_or(0.0),
            });
        }
    }
    Ok(StudyCase {
        whole_machine,
        whole_machine_error,
        ablations,
        noise,
        identified: main.identifiability.identifiable.len(),
        nominal: nominal_err,
        one_iteration: first,
        converged: last,
        x_norms: main.history.iter().map(|h| h.x_norm).collect(),
        reached_tolerance: main.history.last().map(|h| h.x_norm < opts.x_tolerance).unwrap_or(false),
        cross_validation,
        compensation: comp,
    })
}

/// Run the §6 study: draw poses, simulate the actual machine, compute ranks, identify the main and
/// the idle pair noise-free and with noise, cross-validate and compensate.
pub fn run_study(config: &StudyConfig) -> Result<StudyReport, CalibError> {
    use crate::studies::t3r1_machine::ActualMachine;
    use rand::SeedableRng;
    let n = &config.noise;
    if [n.position, n.orientation, n.encoder].iter().any(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(CalibError::InvalidOption(
            "the noisy run's noise (pose position, pose orientation, encoders) must be finite and > 0".into(),
        ));
    }
    let h = &config.workspace.half;
    if [h.x, h.y, h.z, h.yaw].iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
        return Err(CalibError::InvalidOption("the workspace half widths must be finite and ≥ 0".into()));
    }
    if config.identification_poses < 4 || config.validation_poses == 0 {
        return Err(CalibError::InvalidOption(format!(
            "the study needs at least 4 identification poses (12 rows each for up to 40 coordinates) and 1 validation pose, got {} and {}",
            config.identification_poses, config.validation_poses
        )));
    }
    let nominal = T3r1::default();
    let actual = ActualMachine::new(&nominal, &config.errors);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(config.seed);
    let n = config.identification_poses + config.validation_poses;
    let mut sims = Vec::with_capacity(n);
    let mut worst_cond: f64 = 0.0;
    for i in 0..n {
        let kin = |source| CalibError::Kinematics { pose: i, source };
        let target = config.workspace.sample(&mut rng);
        let cmd = nominal.inverse(&target).map_err(kin)?;
        let mut j = nominal.actuator_jacobian(&cmd.sliders).map_err(kin)?;
        // Yaw as the arc (mm) it moves the platform revolutes through: all rows in mm.
        j.row_mut(3).scale_mut(nominal.geometry.a / 2.0);
        let sv = j.singular_values();
        worst_cond = worst_cond.max(sv.max() / sv.min());
        let (truth, pose) = actual.forward(&cmd.sliders).map_err(kin)?;
        sims.push(SimPose { target, truth, pose });
    }
    // Noise-free readings of every drawn pose (no draw from the generator): the identification
    // poses' are the first ones.
    let mut truth_data = measurements(
        &sims,
        ChainPair::ids(false),
        None,
        &mut rand_chacha::ChaCha8Rng::seed_from_u64(config.seed),
    );
    let drawn = full_rank(
        &ChainPair::nominal(&nominal, false),
        &truth_data,
        identifiability::DEFAULT_RANK_TOLERANCE,
    )?;
    truth_data.truncate(config.identification_poses);
    let valid = sims.split_off(config.identification_poses);
    let ident = sims;
    let ranks = ranks(
        &ChainPair::nominal(&nominal, false),
        &truth_data,
        &nominal.geometry,
        identifiability::DEFAULT_RANK_TOLERANCE,
    )?;
    // Lower angles on the actual machine.
    let true_pair = ChainPair {
        chains: [actual.chain(ChainId::B1).clone(), actual.chain(ChainId::B3).clone()],
    };
    let mut check = LowerAngleCheck {
        closure_max_error_deg: 0.0,
        eq25_max_error_deg: 0.0,
        eq25_distance_residual_mm: 0.0,
    };
    for (i, m) in truth_data.iter().enumerate() {
        let kin = |source| CalibError::Kinematics { pose: i, source };
        let truth = m.lower.expect("simulated");
        let q = true_pair.closure(&m.reading, ChainPair::seed()).map_err(kin)?;
        let q25 = lower_angles_eq25(&true_pair, &m.reading, nominal.geometry.a, ChainPair::seed()).map_err(kin)?;
        let a1 = true_pair.chains[0]
            .points(&ChainPair::inputs(&m.reading, 0, q25[0]))
            .map_err(kin)?
            .1;
        let a2 = true_pair.chains[1]
            .points(&ChainPair::inputs(&m.reading, 1, q25[1]))
            .map_err(kin)?
            .1;
        for (k, t) in truth.iter().enumerate() {
            check.closure_max_error_deg = check.closure_max_error_deg.max((q[k] - t).abs().to_degrees());
            check.eq25_max_error_deg = check.eq25_max_error_deg.max((q25[k] - t).abs().to_degrees());
        }
        check.eq25_distance_residual_mm = check.eq25_distance_residual_mm.max(((a2 - a1).norm() - nominal.geometry.a).abs());
    }
    let file = crate::io::model_file::ModelFile::load_or_builtin(&config.model).map_err(|e| CalibError::InvalidOption(e.to_string()))?;
    let whole = WholeMachine::from_file(&file)?;
    let noise_free = run_case(&whole, &nominal, &actual, &ident, &valid, None, config.seed + 1)?;
    let noisy = run_case(&whole, &nominal, &actual, &ident, &valid, Some(config.noise), config.seed + 2)?;
    Ok(StudyReport {
        config: config.clone(),
        ranks,
        lower_angles: check,
        worst_actuator_condition: worst_cond,
        noise_free,
        noisy,
        full_rank: drawn,
    })
}
