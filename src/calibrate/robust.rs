//! The robust identification: a Huber fit, then the poses it down-weighted as blunders set
//! aside and the rest fitted again, until the set is stable; and when the Huber fit sets none
//! aside, a trimmed fit checks that none hides behind it.
use super::{BLUNDER_WEIGHT, MAX_REJECTION_ROUNDS};
use crate::error::CalibError;
use crate::identify::{fit_residuals, huber_threshold, identify, linearize, pose_rms, Identification, Loss, Options};
use crate::io::data_file::DataSet;
use crate::io::IoError;
use crate::measure::{Measurement, Noise};
use crate::model::Mechanism;

/// Share of the poses a trimmed fit is made on (those of smallest residual).
const TRIM_KEEP: f64 = 0.75;

/// Concentration steps of a trimmed fit (each refits on the poses of smallest residual under the
/// last fit; they stop as soon as that set repeats).
const TRIM_STEPS: usize = 6;

/// Fewest poses a trimmed check is made on: below this a quarter of the poses is too few to
/// leave out.
const TRIM_MIN_POSES: usize = 12;

/// The trimmed check runs only on a fit whose `σ̂₀` is above this: blunders that pulled the fit
/// leave its residual far above the noise, and a fit at the noise (most simulations) is spared
/// the extra fits.
const TRIM_ABOVE_SIGMA0: f64 = 3.0;

/// A fit on the poses that are not blunders.
pub struct RobustFit {
    /// The identification on the kept poses (its `delta` counted from the start).
    pub identification: Identification<Box<dyn Mechanism>>,
    /// Indices (into the measurements) of the poses kept in the fit.
    pub kept: Vec<usize>,
}

/// Identify `start` from `measurements` with the loss of `opts`; poses the robust loss weighs
/// below [`BLUNDER_WEIGHT`] are set aside and the fit repeated on the rest, until none is left
/// to set aside (a Huber fit alone still lets many blunders pull together). Each round starts
/// from the start again, not from the previous round's solution, so blunders that pulled the
/// first fit far away (beyond the tolerances) do not leave it in a wrong minimum.
///
/// Several blunders can pull a fit so far that its robust scale (the median pose residual)
/// grows with them and none of them stands out: three poses 25 mm off among thirty left every
/// pose millimetres off. So when the Huber fit sets none aside, a **trimmed fit** (made on the
/// three quarters of the poses of smallest residual, concentrated by refitting until that set
/// repeats; Rousseeuw's least trimmed squares; each a plain Gauss–Newton fit,
/// [`fit_residuals`]) judges the poses again: those beyond twice the
/// Huber threshold of its robust scale are blunders, set aside as above. It runs when the fit's
/// `σ̂₀` is above [`TRIM_ABOVE_SIGMA0`]; data without such blunders keep the Huber fit
/// unchanged. Errors are located in `data`.
pub fn fit_setting_blunders_aside(
    start: &dyn Mechanism,
    measurements: &[Measurement],
    opts: &Options,
    data: &DataSet,
) -> Result<RobustFit, IoError> {
    let start = start.box_clone();
    let mut kept: Vec<usize> = (0..measurements.len()).collect();
    let mut identification = identify(&start, measurements, opts).map_err(|e| data.locate(e))?;
    for _ in 0..MAX_REJECTION_ROUNDS {
        let mut rejected: std::collections::HashSet<usize> = kept
            .iter()
            .zip(&identification.pose_weights)
            .filter(|(_, w)| **w < BLUNDER_WEIGHT)
            .map(|(i, _)| *i)
            .collect();
        if rejected.is_empty() {
            rejected = hidden_blunders(&start, measurements, &kept, &identification, opts)
                .into_iter()
                .collect();
        }
        if rejected.is_empty() {
            break;
        }
        kept.retain(|i| !rejected.contains(i));
        let subset: Vec<Measurement> = kept.iter().map(|&i| measurements[i].clone()).collect();
        let locate = |e: CalibError| match e {
            CalibError::Kinematics { pose, source } => data.locate(CalibError::Kinematics { pose: kept[pose], source }),
            other => data.locate(other),
        };
        identification = identify(&start, &subset, opts).map_err(locate)?;
    }
    Ok(RobustFit { identification, kept })
}

/// Each pose's RMS weighted residual of `measurements` at `model` ([`pose_rms`]); `None` if a
/// pose cannot be predicted.
fn residual_per_pose(model: &dyn Mechanism, measurements: &[Measurement], noise: &Noise) -> Option<Vec<f64>> {
    let lin = linearize(model, measurements, noise).ok()?;
    Some(pose_rms(&lin.residual, &lin.offsets))
}

/// The poses of `kept` (indices into `measurements`) that a trimmed fit shows to be blunders
/// although the Huber fit `fit` did not (see [`fit_setting_blunders_aside`]); empty without a
/// Huber loss, on few poses, or when a trimmed fit cannot be made.
fn hidden_blunders<M: Mechanism + Clone>(
    start: &M,
    measurements: &[Measurement],
    kept: &[usize],
    fit: &Identification<M>,
    opts: &Options,
) -> Vec<usize> {
    let Loss::Huber { k } = opts.loss else {
        return Vec::new();
    };
    if kept.len() < TRIM_MIN_POSES || fit.sigma0.is_nan() || fit.sigma0 <= TRIM_ABOVE_SIGMA0 {
        return Vec::new();
    }
    let all: Vec<Measurement> = kept.iter().map(|&i| measurements[i].clone()).collect();
    let h = ((kept.len() as f64) * TRIM_KEEP).ceil() as usize;
    let Some(mut s) = residual_per_pose(&fit.model, &all, &fit.noise) else {
        return Vec::new();
    };
    let mut trimmed: Vec<usize> = Vec::new();
    for _ in 0..TRIM_STEPS {
        let mut order: Vec<usize> = (0..kept.len()).collect();
        order.sort_by(|&a, &b| s[a].total_cmp(&s[b]).then(a.cmp(&b)));
        let mut next = order[..h].to_vec();
        next.sort_unstable();
        if next == trimmed {
            break;
        }
        trimmed = next;
        let subset: Vec<Measurement> = trimmed.iter().map(|&j| all[j].clone()).collect();
        let Ok(t) = fit_residuals(start, &subset, opts) else {
            return Vec::new();
        };
        match residual_per_pose(&t.model, &all, &t.noise) {
            Some(v) => s = v,
            None => return Vec::new(),
        }
    }
    // The Huber threshold of the trimmed fit's robust scale, and a blunder beyond twice it, as
    // the Huber fit's own rule (weight below BLUNDER_WEIGHT).
    let threshold = huber_threshold(k, &s);
    (0..kept.len())
        .filter(|&j| s[j] * BLUNDER_WEIGHT > threshold)
        .map(|j| kept[j])
        .collect()
}
