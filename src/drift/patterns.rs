//! The named patterns a drift is looked for among: each a direction (or a few) in the model's
//! parameters, found from the model at configurations spread over its workspace.
//!
//! In order (the first of patterns that explain the data equally well is named): each input's
//! offset (a joint offset, a slider's zero), a uniform scale of the machine's lengths about its
//! base (temperature), the tool's position, the measurement frame (the tracker moved), then every
//! single parameter whose effect is not already one of those. An input's offset and the scale
//! are not parameters of every model: each is the parameter direction whose effect on the tool
//! pose is the input's shift (the scale's growth) at every sampled configuration, kept only where
//! the model represents it exactly (to 1e-6 of its effect); a single parameter's effect equal to
//! it is then named as the input's offset.
use crate::error::CalibError;
use crate::measure::{self, Observation};
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::params::Unit;
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use serde::Serialize;

/// Configurations the patterns' directions are found at.
const SAMPLES: usize = 24;

/// A pattern's effect represented by the model's parameters to within this fraction.
const EXACT: f64 = 1e-6;

/// What kind of change a pattern is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PatternKind {
    /// One input's offset (a joint offset; a prismatic input's zero).
    InputOffset,
    /// Every length of the machine grown by the same factor about its base.
    Scale,
    /// The tool's position (re-mounted).
    Tool,
    /// The measurement frame (the instrument moved).
    MeasurementFrame,
    /// One parameter of the model.
    Parameter,
}

/// One coefficient of a pattern, for display: its label, and the factor and unit it is shown in.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Coefficient {
    /// E.g. `"tx"`, or the pattern's name for a one-coefficient pattern.
    pub label: String,
    /// From model units (mm, rad, a pure number) to the unit shown.
    pub factor: f64,
    /// `"mm"`, `"deg"`, `"ppm"`.
    pub unit: &'static str,
}

/// A named change of the model.
#[derive(Debug, Clone, PartialEq)]
pub struct Pattern {
    /// E.g. `"joint q2 offset"`, `"uniform scale of the lengths"`, `"tool position"`, `"2-3.vz"`.
    pub name: String,
    /// What kind.
    pub kind: PatternKind,
    /// The directions in the model's parameters (p × k): the change is `directions·β`.
    pub directions: DMatrix<f64>,
    /// How each of the `k` coefficients `β` is shown.
    pub coefficients: Vec<Coefficient>,
}

fn unit_display(unit: Unit) -> (f64, &'static str) {
    match unit {
        Unit::Dimensionless => (1e6, "ppm"),
        u => u.display(),
    }
}

/// The patterns of `model` (see the [module docs](self)), found at [`SAMPLES`] configurations drawn
/// from `seed` ([`crate::simulate::random_configurations`]) among `inputs` (the model file's).
pub fn patterns(model: &dyn Mechanism, inputs: &[InputSpec], seed: u64) -> Result<Vec<Pattern>, CalibError> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let configurations = crate::simulate::random_configurations(model, inputs, SAMPLES, &mut rng)
        .map_err(|source| CalibError::Kinematics { pose: 0, source })?;
    let params = model.params();
    let p = params.len();
    // The effect of each parameter (columns) and the predicted poses at the samples.
    let mut poses = Vec::new();
    let mut blocks = Vec::new();
    for (i, q) in configurations.iter().enumerate() {
        let (pose, jac) = model
            .forward_with_jacobian(q)
            .map_err(|source| CalibError::Kinematics { pose: i, source })?;
        blocks.push(measure::residual_jacobian(&Observation::Pose(pose), &pose, &jac));
        poses.push(pose);
    }
    let rows = 6 * blocks.len();
    let effect = DMatrix::from_fn(rows, p, |r, c| blocks[r / 6][(r % 6, c)]);
    let norms: Vec<f64> = (0..p).map(|c| effect.column(c).norm()).collect();
    let top = norms.iter().copied().fold(0.0, f64::max);
    let seen = |c: usize| norms[c] > 1e-9 * top;
    let in_measurement_frame = |c: usize| params[c].group == "measurement frame";
    // Parameters a machine's change may be represented in.
    // (Not those an overconstrained machine cannot take alone.)
    let held = model.assembly_breaking();
    let machine: Vec<usize> = (0..p)
        .filter(|&c| seen(c) && !in_measurement_frame(c) && !held.contains(&c))
        .collect();
    let mut out: Vec<(Pattern, DMatrix<f64>)> = Vec::new();
    // Each input's offset: the pose's change per unit of the input, by central differences.
    let frames = model.frames();
    for (j, input) in inputs.iter().enumerate() {
        if input.observed || input.approach_of.is_some() || input.unit == Unit::Dimensionless {
            continue;
        }
        let h = if input.unit == Unit::Angle { 1e-6 } else { 1e-4 };
        let mut g = DVector::zeros(rows);
        for (i, q) in configurations.iter().enumerate() {
            let shifted = |s: f64| {
                let mut q = q.clone();
                q[j] += s;
                model.forward(&q)
            };
            let (Ok(plus), Ok(minus)) = (shifted(h), shifted(-h)) else {
                g.fill(f64::NAN);
                break;
            };
            let obs = Observation::Pose(poses[i]);
            let (rp, rm) = (measure::residual(&obs, &plus), measure::residual(&obs, &minus));
            for k in 0..6 {
                g[6 * i + k] = (rm[k] - rp[k]) / (2.0 * h);
            }
        }
        let what = if input.unit == Unit::Angle { "offset" } else { "zero" };
        let name = format!("joint {} {what}", input.name);
        if let Some(d) = represent(&effect, &g, &machine, &norms) {
            let (factor, unit) = unit_display(input.unit);
            out.push((
                Pattern {
                    name: name.clone(),
                    kind: PatternKind::InputOffset,
                    directions: DMatrix::from_column_slice(p, 1, d.as_slice()),
                    coefficients: vec![Coefficient { label: name, factor, unit }],
                },
                DMatrix::from_column_slice(rows, 1, g.as_slice()),
            ));
        }
    }
    // A uniform scale about the base: every predicted position moves by s·(p − base origin).
    let origin = frames.map_or(nalgebra::Vector3::zeros(), |(m, _)| m.translation.vector);
    let mut g = DVector::zeros(rows);
    for (i, pose) in poses.iter().enumerate() {
        let grown = |s: f64| -> Pose {
            let mut t = *pose;
            t.translation.vector += s * (pose.translation.vector - origin);
            t
        };
        let obs = Observation::Pose(*pose);
        let (rp, rm) = (measure::residual(&obs, &grown(1e-6)), measure::residual(&obs, &grown(-1e-6)));
        for k in 0..6 {
            g[6 * i + k] = (rm[k] - rp[k]) / 2e-6;
        }
    }
    if let Some(d) = represent(&effect, &g, &machine, &norms) {
        let name = "uniform scale of the lengths".to_string();
        out.push((
            Pattern {
                name: name.clone(),
                kind: PatternKind::Scale,
                directions: DMatrix::from_column_slice(p, 1, d.as_slice()),
                coefficients: vec![Coefficient {
                    label: name,
                    factor: 1e6,
                    unit: "ppm",
                }],
            },
            DMatrix::from_column_slice(rows, 1, g.as_slice()),
        ));
    }
    // The tool's position; the measurement frame.
    let group = |names: &[&str], lengths_only: bool| -> Vec<usize> {
        (0..p)
            .filter(|&c| names.contains(&params[c].group.as_str()) && seen(c) && !held.contains(&c))
            .filter(|&c| !lengths_only || params[c].unit == Unit::Length)
            .collect()
    };
    let mut tool = group(&["tool frame"], true);
    if tool.is_empty() {
        tool = group(&["tool"], true);
    }
    for (cols, name, kind) in [
        (tool, "tool position", PatternKind::Tool),
        (
            group(&["measurement frame"], false),
            "measurement frame",
            PatternKind::MeasurementFrame,
        ),
    ] {
        if cols.is_empty() {
            continue;
        }
        let mut d = DMatrix::zeros(p, cols.len());
        for (k, &c) in cols.iter().enumerate() {
            d[(c, k)] = 1.0;
        }
        let coefficients = cols
            .iter()
            .map(|&c| {
                let (factor, unit) = unit_display(params[c].unit);
                Coefficient {
                    label: params[c].name.clone(),
                    factor,
                    unit,
                }
            })
            .collect();
        let g = &effect * &d;
        out.push((
            Pattern {
                name: name.into(),
                kind,
                directions: d,
                coefficients,
            },
            g,
        ));
    }
    // Single parameters, unless their effect is already a one-coefficient pattern's.
    for &c in &machine {
        let col = effect.column(c);
        let duplicate = out.iter().any(|(pat, g)| {
            g.ncols() == 1 && pat.kind != PatternKind::Parameter && {
                let gn = g.column(0).norm();
                gn > 0.0 && (col.dot(&g.column(0)).abs() / (norms[c] * gn)) > 1.0 - 1e-9
            }
        });
        if duplicate {
            continue;
        }
        let mut d = DMatrix::zeros(p, 1);
        d[(c, 0)] = 1.0;
        let (factor, unit) = unit_display(params[c].unit);
        out.push((
            Pattern {
                name: params[c].name.clone(),
                kind: PatternKind::Parameter,
                directions: d,
                coefficients: vec![Coefficient {
                    label: params[c].name.clone(),
                    factor,
                    unit,
                }],
            },
            DMatrix::from_column_slice(rows, 1, col.as_slice()),
        ));
    }
    Ok(out.into_iter().map(|(pat, _)| pat).collect())
}

/// The parameter direction `d` (over `cols`) with `effect·d = g`, when one exists to [`EXACT`]:
/// a single parameter when one suffices, else the minimum-norm one over the scaled columns.
fn represent(effect: &DMatrix<f64>, g: &DVector<f64>, cols: &[usize], norms: &[f64]) -> Option<DVector<f64>> {
    let gn = g.norm();
    if !(gn.is_finite() && gn > 0.0) {
        return None;
    }
    let p = effect.ncols();
    for &c in cols {
        let a = effect.column(c);
        let x = a.dot(g) / (norms[c] * norms[c]);
        if (g - a * x).norm() <= EXACT * gn {
            let mut d = DVector::zeros(p);
            d[c] = x;
            return Some(d);
        }
    }
    let scaled = DMatrix::from_fn(effect.nrows(), cols.len(), |r, k| effect[(r, cols[k])] / norms[cols[k]]);
    let svd = scaled.clone().svd(true, true);
    let top = svd.singular_values.iter().copied().fold(0.0, f64::max);
    let y = svd.solve(g, 1e-10 * top).ok()?;
    if (&scaled * &y - g).norm() > EXACT * gn {
        return None;
    }
    let mut d = DVector::zeros(p);
    for (k, &c) in cols.iter().enumerate() {
        d[c] = y[k] / norms[c];
    }
    Some(d)
}
