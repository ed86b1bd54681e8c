//! Other starts of the identification: the geometry perturbed within a third of the model's
//! tolerances, the same frames. The lowest residual is kept; predictions that disagree name a
//! fit with several minima.
use super::{StartOutcome, START_AGREEMENT, START_POSES};
use crate::identify::{identify, Agreement, Identification, Options};
use crate::io::data_file::DataSet;
use crate::io::model_file::Tolerances;
use crate::io::IoError;
use crate::measure::Measurement;
use crate::model::Mechanism;

/// A random perturbation of the free, non-frame geometric parameters: uniform within a third of
/// the tolerance of each parameter's unit (lengths in mm, angles in rad).
fn perturbation(model: &dyn Mechanism, free: &[usize], tol: &Tolerances, seed: u64) -> nalgebra::DVector<f64> {
    use rand::{RngExt, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let params = model.params();
    let mut d = nalgebra::DVector::zeros(params.len());
    for &i in free {
        if params[i].is_placement() {
            continue;
        }
        let s = tol.of(params[i].unit).map_or(0.0, |t| t / 3.0);
        d[i] = rng.random_range(-s..=s);
    }
    d
}

/// Largest distance (mm) between the tool positions two models predict at the poses of `data`;
/// the first pose where `a` (a start's solution) or `b` (the kept one) cannot be evaluated is
/// the error.
fn max_prediction_difference(a: &dyn Mechanism, b: &dyn Mechanism, data: &[Measurement]) -> Result<f64, String> {
    let mut max: f64 = 0.0;
    for (i, m) in data.iter().enumerate() {
        let x = a
            .forward(&m.q)
            .map_err(|e| format!("its solution at identification pose {i}: {e}"))?;
        let y = b
            .forward(&m.q)
            .map_err(|e| format!("the kept solution at identification pose {i}: {e}"))?;
        max = max.max((crate::measure::compared_point(&m.obs, &x) - crate::measure::compared_point(&m.obs, &y)).norm());
    }
    Ok(max)
}

/// What the starts gave: the kept identification and each start's outcome (the kept one first).
pub struct Starts {
    /// The kept identification, on every kept pose.
    pub identification: Identification<Box<dyn Mechanism>>,
    /// Each start's outcome, the kept one first.
    pub outcomes: Vec<StartOutcome>,
}

/// The inputs the other starts share.
pub struct StartSetup<'a> {
    /// The starting model (nominal geometry in the registered frames).
    pub start: &'a dyn Mechanism,
    /// Free parameters.
    pub free: &'a [usize],
    /// The model's tolerances (the perturbations are a third of them).
    pub tolerances: &'a Tolerances,
    /// Identification options of the main fit.
    pub opts: &'a Options,
    /// Number of starts, the main fit included.
    pub starts: u64,
    /// Seed of the perturbations.
    pub seed: u64,
}

/// Run `setup.starts − 1` perturbed starts beside `fit` (the fit of the registered start on the
/// kept poses `kept` of `measurements`) and keep the best. On large sets they run on an evenly
/// spread subset of [`START_POSES`] poses, the main fit polished there for the comparison, and a
/// winner other than the main fit is refitted on every kept pose.
pub fn other_starts(
    setup: &StartSetup,
    fit: Identification<Box<dyn Mechanism>>,
    measurements: &[Measurement],
    kept: &[usize],
    data: &DataSet,
) -> Result<Starts, IoError> {
    let id_opts = setup.opts;
    let stride = kept.len().div_ceil(START_POSES).max(1);
    let subset: Vec<Measurement> = kept.iter().step_by(stride).map(|&i| measurements[i].clone()).collect();
    // A start whose predictions come within a hundredth of the noise of the first fit's has
    // entered its basin: it agrees, and is not iterated to the end.
    let agree_opts = Options {
        agree_with: (setup.starts > 1)
            .then(|| -> Option<Agreement> {
                let positions = subset
                    .iter()
                    .map(|m| fit.model.forward(&m.q).ok().map(|t| crate::measure::compared_point(&m.obs, &t)))
                    .collect::<Option<Vec<_>>>()?;
                Some(Agreement {
                    positions,
                    tolerance_mm: START_AGREEMENT * id_opts.noise.position,
                    identifiability: (stride == 1).then(|| fit.identifiability.clone()),
                })
            })
            .flatten(),
        ..id_opts.clone()
    };
    let mut others = Vec::new();
    for k in 1..setup.starts.max(1) as usize {
        let pert = perturbation(setup.start, setup.free, setup.tolerances, setup.seed.wrapping_add(k as u64));
        let mut perturbed = setup.start.box_clone();
        perturbed.retract(&pert);
        // A start that fails outright (the perturbed machine does not assemble at some pose)
        // cannot be compared: it is dropped from the agreement check, with its reason.
        let outcome = identify(&perturbed, &subset, &agree_opts)
            .map(|r| {
                let delta = pert + &r.delta;
                Identification { delta, ..r }
            })
            .map_err(|e| e.to_string());
        others.push(outcome);
    }
    // On a subset, the fit on every pose is compared with the other starts on the same poses:
    // polished there first (one or two iterations from its solution).
    let (first, full_fit) = if stride > 1 {
        let on_subset = identify(&fit.model, &subset, id_opts)
            .map(|r| {
                let delta = fit.delta.clone() + &r.delta;
                Identification { delta, ..r }
            })
            .map_err(|e| e.to_string());
        (on_subset, Some(fit))
    } else {
        (Ok(fit), None)
    };
    let mut all: Vec<Result<Identification<Box<dyn Mechanism>>, String>> = vec![first];
    all.extend(others);
    // The registered start is kept unless another reaches a clearly lower residual: equal fits
    // from perturbed starts differ only in how redundant directions were split.
    let sigma = |k: usize| {
        all[k]
            .as_ref()
            .ok()
            .filter(|r| r.converged && r.sigma0.is_finite())
            .map_or(f64::INFINITY, |r| r.sigma0)
    };
    let mut best = 0;
    for k in 1..all.len() {
        if sigma(k) < sigma(best) * (1.0 - 1e-6) || (sigma(best).is_infinite() && sigma(k).is_finite()) {
            best = k;
        }
    }
    let reference = all[best].as_ref().ok().map(|r| r.model.box_clone());
    let outcomes: Vec<StartOutcome> = std::iter::once(best)
        .chain((0..all.len()).filter(|&k| k != best))
        .map(|k| {
            let compared = match (&all[k], &reference) {
                _ if k == best => Ok(0.0),
                (Ok(r), Some(reference)) => max_prediction_difference(&*r.model, &**reference, &subset),
                (Ok(_), None) => Ok(0.0),
                (Err(e), _) => Err(format!("its fit failed: {e}")),
            };
            let (sigma0, converged) = all[k].as_ref().map_or((f64::NAN, false), |r| (r.sigma0, r.converged));
            StartOutcome {
                sigma0,
                converged,
                max_difference_mm: compared.as_ref().ok().copied(),
                unchecked: compared.err(),
            }
        })
        .collect();
    let chosen = std::mem::replace(&mut all[best], Err(String::new())).ok();
    let identification = match (full_fit, best) {
        (Some(full), 0) => full,
        // Another start won on the subset: its solution, refitted on every kept pose.
        (Some(full), _) => match chosen {
            Some(c) => {
                let kept_data: Vec<Measurement> = kept.iter().map(|&i| measurements[i].clone()).collect();
                let r = identify(&c.model, &kept_data, id_opts).map_err(|e| data.locate(e))?;
                let delta = c.delta + &r.delta;
                Identification { delta, ..r }
            }
            None => full,
        },
        (None, _) => chosen.expect("the best start has a result"),
    };
    Ok(Starts { identification, outcomes })
}

/// A start whose σ̂₀ is above this many times the kept one's (plus [`WORSE_MARGIN`]) ended in a
/// clearly worse minimum: a cost more than twice the kept one's, beyond chance for any fit with
/// a few rows to spare. It does not question the kept solution and is set aside from the
/// agreement check (a flag names it); starts that fit about as well and predict differently do.
pub const WORSE_MINIMUM: f64 = 1.5;

/// The σ̂₀ margin of [`WORSE_MINIMUM`] (in units of the stated noise): noise-free fits end at
/// σ̂₀ ≈ 0, where a ratio says nothing.
pub const WORSE_MARGIN: f64 = 0.05;

impl StartOutcome {
    /// Whether this start ended in a clearly worse minimum than a kept solution of σ̂₀ `kept`
    /// ([`WORSE_MINIMUM`], [`WORSE_MARGIN`]).
    pub fn clearly_worse_than(&self, kept: f64) -> bool {
        self.sigma0.is_finite() && self.sigma0 > WORSE_MINIMUM * kept + WORSE_MARGIN
    }
}

/// What the starts' agreement says ([`start_agreement`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StartAgreement {
    /// Starts left out of the check (not comparable, or a clearly worse minimum).
    pub flags: Vec<String>,
    /// No other start could be compared at all.
    pub warning: Option<String>,
    /// Starts that fit about as well predict differently: the verdict fails.
    pub failure: Option<String>,
}

/// The starts' agreement: the kept solution (first of `outcomes`) against every other start that
/// fits about as well (not beyond [`WORSE_MINIMUM`]); predictions more than `tolerance_mm` apart
/// are a failure naming the starts' σ̂₀. Starts left out (not comparable, or a clearly worse
/// minimum) are flags; none compared at all is a warning.
pub fn start_agreement(outcomes: &[StartOutcome], tolerance_mm: f64) -> StartAgreement {
    let mut out = StartAgreement::default();
    let kept = outcomes.first().map_or(0.0, |s| s.sigma0);
    let worse = |s: &StartOutcome| s.clearly_worse_than(kept);
    let worse_starts: Vec<String> = (outcomes.iter().enumerate())
        .filter(|(_, s)| s.max_difference_mm.is_some() && worse(s))
        .map(|(k, s)| format!("start {} (σ̂₀ {:.3})", k + 1, s.sigma0))
        .collect();
    if !worse_starts.is_empty() {
        out.flags.push(format!(
            "{} of {} starts ended in a clearly worse minimum than the kept one (σ̂₀ {kept:.3}), set aside from the agreement check: {}",
            worse_starts.len(),
            outcomes.len(),
            worse_starts.join("; ")
        ));
    }
    let compared: Vec<&StartOutcome> = outcomes.iter().filter(|s| s.max_difference_mm.is_some() && !worse(s)).collect();
    let spread = compared.iter().filter_map(|s| s.max_difference_mm).fold(0.0, f64::max);
    let unchecked: Vec<String> = (outcomes.iter().enumerate())
        .filter_map(|(k, s)| s.unchecked.as_ref().map(|why| format!("start {} ({why})", k + 1)))
        .collect();
    if !unchecked.is_empty() {
        out.flags.push(format!(
            "{} of {} starts left out of the agreement check, not comparable: {}",
            unchecked.len(),
            outcomes.len(),
            unchecked.join("; ")
        ));
        if unchecked.len() + 1 == outcomes.len() {
            out.warning = Some(format!(
                "no other start could be compared with the kept solution ({} left out: their perturbed machines could not be evaluated at every pose), so whether the fit has other minima was not checked: run again with another --seed or more --starts",
                unchecked.len()
            ));
        }
    }
    if spread > tolerance_mm {
        let sigmas: Vec<String> = compared.iter().map(|s| format!("{:.3}", s.sigma0)).collect();
        out.failure = Some(format!(
            "the {} starts disagree: their predictions differ by up to {spread:.4} mm (more than the noise, {:.4} mm; σ̂₀ {}): the fit has several minima here and the kept one (the lowest) may not be the true geometry: check the nominal model and the tolerances, add or spread the poses, or fix parameters",
            compared.len(),
            tolerance_mm,
            sigmas.join(" / ")
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(sigma0: f64, difference: f64) -> StartOutcome {
        StartOutcome {
            sigma0,
            converged: true,
            max_difference_mm: Some(difference),
            unchecked: None,
        }
    }

    /// Starts that fit about as well and predict differently fail; a start in a clearly worse
    /// minimum is set aside (a flag), however far its predictions are.
    #[test]
    fn only_starts_that_fit_about_as_well_can_disagree() {
        let equal = start_agreement(&[outcome(1.2, 0.0), outcome(1.25, 0.5), outcome(1.3, 0.01)], 0.08);
        assert!(
            equal.failure.as_deref().is_some_and(|f| f.contains("the 3 starts disagree")),
            "{equal:?}"
        );
        let worse = start_agreement(&[outcome(1.337, 0.0), outcome(1.337, 0.01), outcome(16.7, 0.81)], 0.08);
        assert_eq!(worse.failure, None, "{worse:?}");
        assert!(worse.flags[0].contains("start 3 (σ̂₀ 16.700)"), "{worse:?}");
        // Noise-free: σ̂₀ ≈ 0 for the kept fit; a start at 0.001 still counts, one at 0.43 does not.
        let exact = start_agreement(&[outcome(0.0, 0.0), outcome(0.001, 265.0)], 0.06);
        assert!(exact.failure.is_some(), "{exact:?}");
        let apart = start_agreement(&[outcome(0.0, 0.0), outcome(0.43, 265.0)], 0.06);
        assert_eq!(apart.failure, None, "{apart:?}");
    }
}
