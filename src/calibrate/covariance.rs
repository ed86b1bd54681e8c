//! The calibrated model file's `[covariance]`: the identification's covariance on the
//! parameters of the model the file builds, and why each other parameter has none.
use crate::identify::Identification;
use crate::io::model_file::{Covariance, Held, ModelFile};
use crate::measure::Measurement;
use crate::model::Mechanism;

/// Most identification poses whose residuals a calibrated model file carries
/// ([`Covariance::residuals`]); beyond this many, evenly spaced among them.
pub const MAX_RESIDUAL_POSES: usize = 1000;

/// The covariance of `identification` (whose free parameters, in its model's indices, were
/// `free`, its poses `poses`) over the parameters of `file.build()` that it identified; the model's other parameters
/// held, with why (a parameter of the fit that the file's model does not have — an instrument's
/// artifact point — is left out: the matrix is the marginal one). The configurations it is
/// carried at are drawn on `drawing`, the model the calibration started from.
pub(crate) fn of(
    file: &ModelFile,
    drawing: &ModelFile,
    identification: &Identification<Box<dyn Mechanism>>,
    free: &[usize],
    poses: &[Measurement],
) -> Covariance {
    let fitted = identification.model.params();
    let id = &identification.identifiability;
    let mut identified = Vec::new();
    let mut held = Vec::new();
    for p in file.build().params() {
        let Some(k) = fitted.iter().position(|f| f.name == p.name) else {
            held.push((p.name, Held::Fixed));
            continue;
        };
        let why = if id.identifiable.contains(&k) {
            identified.push((k, p));
            continue;
        } else if id.weak.contains(&k) {
            Held::Weak
        } else if id.gauge.contains(&k) {
            Held::Placement
        } else if free.contains(&k) {
            Held::Redundant
        } else {
            Held::Fixed
        };
        held.push((p.name, why));
    }
    let carried = in_file_coordinates(file, drawing, identification, &identified);
    let c = carried.as_ref().unwrap_or(&identification.covariance);
    Covariance {
        matrix: nalgebra::DMatrix::from_fn(identified.len(), identified.len(), |i, j| {
            // Symmetric to the last bit, as the file requires.
            let (a, b) = (identified[i].0.min(identified[j].0), identified[i].0.max(identified[j].0));
            c[(a, b)]
        }),
        names: identified.iter().map(|(_, p)| p.name.clone()).collect(),
        units: identified.iter().map(|(_, p)| p.unit).collect(),
        sigma0: identification.sigma0,
        residuals: pose_residuals(identification, poses),
        held,
    }
}

/// The identification's covariance carried to the coordinates of the model `file` builds
/// ([`crate::predict::carry_covariance`] onto the `identified` parameters, at
/// [`crate::predict::CARRY_CONFIGURATIONS`] configurations drawn from seed 1 on `drawing`, the
/// model the calibration started from: the configurations its workspace commands, drawn alike
/// however far the fit went (a fit gone far from the drawing, on wrong data, may reach little of
/// that workspace, and drawing there would take thousands of failed solves)): the rebuilt model
/// holds the calibrated geometry with its errors at zero, so its Jacobian is not the fitted
/// model's. `None` where the fitted model is not the file's (an instrument's artifact points
/// around it: its parameters are not the file's) or it cannot be evaluated; the covariance is then
/// written as identified.
fn in_file_coordinates(
    file: &ModelFile,
    drawing: &ModelFile,
    identification: &Identification<Box<dyn Mechanism>>,
    identified: &[(usize, crate::params::Param)],
) -> Option<nalgebra::DMatrix<f64>> {
    use rand::SeedableRng;
    let model = file.build();
    let fitted = &identification.model;
    let same = |a: &dyn Mechanism, b: &dyn Mechanism| {
        a.input_names() == b.input_names() && a.params().iter().map(|p| &p.name).eq(b.params().iter().map(|p| &p.name))
    };
    if !same(&*model, &**fitted) {
        return None;
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let q = crate::simulate::random_configurations(&*drawing.build(), &drawing.inputs(), crate::predict::CARRY_CONFIGURATIONS, &mut rng)
        .ok()?;
    let onto: Vec<usize> = identified.iter().map(|(k, _)| *k).collect();
    crate::predict::carry_covariance(&*model, &**fitted, &identification.covariance, &q, &onto).ok()
}

/// Configurations drawn over the workspace for the report's map of predicted accuracy.
pub(crate) const MAP_CONFIGURATIONS: usize = 200;

/// The report's map of predicted accuracy: the calibrated model file's predicted position σ
/// ([`crate::predict::accuracy_of_file`]) at the measured configurations (of `sets`, each
/// cut to the model's inputs) and at [`MAP_CONFIGURATIONS`] drawn over the workspace of
/// `drawing` (the model the calibration started from: the configurations its workspace commands)
/// with `seed`; configurations where the calibrated model cannot be evaluated are left out.
/// `None` without a covariance.
pub(crate) fn predicted_map(
    file: &ModelFile,
    drawing: &ModelFile,
    sets: &[&[crate::measure::Measurement]],
    seed: u64,
) -> Option<crate::report::PredictedMap> {
    use rand::SeedableRng;
    let model = file.build();
    let names: Vec<String> = model.params().into_iter().map(|p| p.name).collect();
    let covariance = file.covariance.as_ref()?.over(&names);
    let noise = file.noise.unwrap_or_default();
    let n = model.input_names().len();
    let mut configurations: Vec<(Vec<f64>, bool)> = Vec::new();
    for set in sets {
        for m in set.iter().filter(|m| m.q.len() >= n && !crate::report::is_known_distance(m)) {
            configurations.push((m.q[..n].to_vec(), true));
        }
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    if let Ok(drawn) = crate::simulate::random_configurations(&*drawing.build(), &drawing.inputs(), MAP_CONFIGURATIONS, &mut rng) {
        configurations.extend(drawn.into_iter().map(|q| (q, false)));
    }
    let mut map = crate::report::PredictedMap::default();
    for (q, measured) in configurations {
        let Ok(acc) = crate::predict::accuracy(&*model, &covariance, &noise, std::slice::from_ref(&q)) else {
            continue;
        };
        map.noise_mm = acc.noise_position_mm;
        let p = &acc.poses[0];
        map.positions.push(p.position);
        map.sigma_mm.push(p.position_mm);
        map.measured.push(measured);
    }
    (!map.sigma_mm.is_empty()).then_some(map)
}

/// Each of the `fitted` poses' residual rows at the identified model, in units of the judged
/// noise (the stated noise times `σ̂₀`) and scaled by `√(rows / (rows − parameters))`, the
/// shrinkage of a fitted residual undone: as a pose the fit did not see would leave them. Only
/// where `σ̂₀` is above 1 (otherwise the stated noise describes the residual); at most
/// [`MAX_RESIDUAL_POSES`] poses; to four decimals.
fn pose_residuals(identification: &Identification<Box<dyn Mechanism>>, fitted: &[Measurement]) -> Vec<Vec<f64>> {
    let s0 = identification.sigma0;
    if !(s0.is_finite() && s0 > 1.0) || fitted.is_empty() {
        return Vec::new();
    }
    let Ok(lin) = crate::identify::linearize(&*identification.model, fitted, &identification.noise) else {
        return Vec::new();
    };
    let rows = lin.residual.len();
    let p = identification.identifiability.identifiable.len();
    if rows <= p {
        return Vec::new();
    }
    let scale = (rows as f64 / (rows - p) as f64).sqrt() / s0;
    let n = fitted.len();
    let take = n.min(MAX_RESIDUAL_POSES);
    (0..take)
        // To the four decimals the file holds: the calibration in memory and read back alike.
        .map(|k| {
            lin.pose_rows(k * n / take)
                .map(|r| (lin.residual[r] * scale * 1e4).round() / 1e4)
                .collect()
        })
        .collect()
}
