//! Plausibility checks of the data against the model before anything is fitted: mistakes a
//! file can hold that would otherwise come out as a wrong calibration: the units of the joint
//! values and of the measured positions, known seat distances, and (after the fit) a stated noise
//! far larger than the residual.
use crate::io::data_file::DataSet;
use crate::io::model_file::ModelFile;
use crate::io::IoError;
use crate::params::Unit;
use std::f64::consts::PI;

/// The largest value (rad) radians can take on a joint: π, or its limits' when larger (±2π on
/// an arm whose wrists turn twice).
fn radians_bound(limits: Option<(f64, f64)>) -> f64 {
    limits.map_or(PI, |(lo, hi)| lo.abs().max(hi.abs()).max(PI))
}

/// The angle columns (by input index) whose every value, read in degrees, stays within what
/// radians can be ([`radians_bound`]) while the joint's limits allow far more.
fn radian_like(model: &ModelFile, data: &DataSet) -> Vec<usize> {
    model
        .inputs()
        .iter()
        .enumerate()
        .filter(|(_, i)| i.unit == Unit::Angle)
        .filter(|(_, i)| i.limits.is_none_or(|(lo, hi)| hi - lo > 4.0 * radians_bound(i.limits).to_radians()))
        .filter(|(k, i)| {
            let max = largest_value(data, *k);
            max > 0.0 && max <= radians_bound(i.limits).to_radians() * 1.0001
        })
        .map(|(k, _)| k)
        .collect()
}

/// The largest magnitude of input `k` over the rows of `data` that carry it (a known distance
/// between two seats carries no configuration).
fn largest_value(data: &DataSet, k: usize) -> f64 {
    data.measurements
        .iter()
        .filter_map(|m| m.q.get(k))
        .map(|v| v.abs())
        .fold(0.0, f64::max)
}

/// Angle columns whose every value, read in degrees, stays within what radians can be while the
/// joint's limits allow far more ([`radian_like`]), two or more and at least half of them, are
/// almost certainly in the wrong unit: refused before any fit.
pub fn plausible_angles(model: &ModelFile, data: &DataSet) -> Result<(), IoError> {
    if data.measurements.len() < 10 {
        return Ok(());
    }
    let inputs = model.inputs();
    let suspicious: Vec<&str> = radian_like(model, data).into_iter().map(|k| inputs[k].name.as_str()).collect();
    if suspicious.len() >= 2 && suspicious.len() * 2 >= inputs.iter().filter(|i| i.unit == Unit::Angle).count() {
        let largest = inputs
            .iter()
            .filter(|i| suspicious.contains(&i.name.as_str()))
            .map(|i| radians_bound(i.limits))
            .fold(PI, f64::max);
        return Err(IoError::Invalid {
            path: data.path.clone(),
            message: format!(
                "the angle columns {} never leave ±{largest:.4} degrees, where their limits allow far more: they look like radians; name them {}_rad (or convert them to degrees)",
                suspicious.join(", "),
                suspicious[0]
            ),
        });
    }
    Ok(())
}

/// A single angle column that looks like radians ([`radian_like`]) is not refused before the
/// fit (a joint can stay near its zero over a set of poses), but named where the fit then fails
/// with corrections far beyond the tolerances: `j2 (never beyond ±2.4419 in its degree column,
/// its limits ±140): radians?`. Empty on fewer than 10 poses.
pub fn radian_like_columns(model: &ModelFile, data: &DataSet) -> Vec<String> {
    if data.measurements.len() < 10 {
        return Vec::new();
    }
    let inputs = model.inputs();
    radian_like(model, data)
        .into_iter()
        .map(|k| {
            let max = largest_value(data, k);
            let limits = inputs[k]
                .limits
                .map(|(lo, hi)| format!(", its limits {:.0}..{:.0}", lo.to_degrees(), hi.to_degrees()))
                .unwrap_or_default();
            format!(
                "{} (never beyond ±{:.4} in its degree column{limits}): radians?",
                inputs[k].name,
                max.to_degrees()
            )
        })
        .collect()
}

/// Unit factors a mistaken file shows: metres or inches for millimetres (and back).
const LENGTH_FACTORS: [(f64, &str); 4] = [
    (1000.0, "metres"),
    (0.001, "micrometres"),
    (25.4, "inches"),
    (1.0 / 25.4, "tenths of a millimetre"),
];

/// Which of `LENGTH_FACTORS` a ratio is, within 15 %.
fn length_factor(ratio: f64) -> Option<(f64, &'static str)> {
    LENGTH_FACTORS
        .into_iter()
        .find(|(f, _)| ratio.is_finite() && ratio > 0.0 && (ratio / f).ln().abs() < 0.15)
}

/// Median of positive values (0 when empty).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

/// Up to `n` rows evenly spread over the rows `rows`.
fn spread(rows: &[usize], n: usize) -> Vec<usize> {
    let step = rows.len().div_ceil(n).max(1);
    rows.iter().step_by(step).copied().collect()
}

/// The nominal tool positions at rows `rows` of `data` with the inputs of unit `unit` multiplied
/// by `factor` (`None` for a row where the model does not assemble).
fn tool_points(
    model: &dyn crate::Mechanism,
    inputs: &[crate::io::model_file::InputSpec],
    data: &DataSet,
    rows: &[usize],
    scale: Option<(Unit, f64)>,
) -> Vec<Option<nalgebra::Vector3<f64>>> {
    rows.iter()
        .map(|&i| {
            let mut q = data.measurements[i].q.clone();
            if let Some((unit, f)) = scale {
                for (v, s) in q.iter_mut().zip(inputs) {
                    if s.unit == unit && s.approach_of.is_none() {
                        *v *= f;
                    }
                }
            }
            model.forward(&q).ok().map(|p| p.translation.vector)
        })
        .collect()
}

/// Wrong units in the data, judged before fitting from what no frame changes: the distances
/// between measured positions against the nominal model's distances between its tool points.
/// Positions about 1000× or 25.4× off the model's (metres or inches in `_mm` columns), and joint
/// values that fit the model far better read in another unit (radians in `_deg` columns, metres
/// in `_mm` ones) are one line naming the likely mistake with the figures. Data without measured
/// positions (seats, distances, touches) pass.
pub fn plausible_units(model: &ModelFile, data: &DataSet) -> Result<(), IoError> {
    use crate::measure::Observation;
    let rows: Vec<usize> = (0..data.measurements.len())
        .filter(|&i| matches!(data.measurements[i].obs, Observation::Pose(_) | Observation::Position(_)))
        .collect();
    if rows.len() < 8 {
        return Ok(());
    }
    let rows = spread(&rows, 40);
    let measured: Vec<nalgebra::Vector3<f64>> = rows
        .iter()
        .map(|&i| match &data.measurements[i].obs {
            Observation::Pose(p) => p.translation.vector,
            Observation::Position(v) => *v,
            _ => nalgebra::Vector3::zeros(),
        })
        .collect();
    let mech = model.build();
    let inputs = model.inputs();
    // Distances between every pair of the rows that assemble; the RMS difference and the
    // medians of both.
    let compare = |points: &[Option<nalgebra::Vector3<f64>>]| -> Option<(f64, f64, f64)> {
        let ok = points.iter().filter(|p| p.is_some()).count();
        if 2 * ok < points.len() {
            return None;
        }
        let (mut diff, mut dm, mut dn) = (Vec::new(), Vec::new(), Vec::new());
        for a in 0..points.len() {
            for b in a + 1..points.len() {
                if let (Some(p), Some(q)) = (points[a], points[b]) {
                    let (m, n) = ((measured[a] - measured[b]).norm(), (p - q).norm());
                    diff.push((m - n).powi(2));
                    dm.push(m);
                    dn.push(n);
                }
            }
        }
        let rms = (diff.iter().sum::<f64>() / diff.len().max(1) as f64).sqrt();
        Some((rms, median(dm), median(dn)))
    };
    let Some((stated, measured_median, model_median)) = compare(&tool_points(&*mech, &inputs, data, &rows, None)) else {
        return Ok(());
    };
    if stated <= 0.05 * model_median.max(1.0) {
        return Ok(());
    }
    if let Some((f, what)) = length_factor(model_median / measured_median.max(1e-300)) {
        return Err(IoError::Invalid {
            path: data.path.clone(),
            message: format!(
                "the measured positions are about {} the model's reach (median distance between poses {measured_median:.4} mm measured, {model_median:.1} mm by the nominal model): {what} in the _mm columns? ({})",
                if f >= 1.0 { format!("1/{f} of") } else { format!("{}×", 1.0 / f) },
                if f == 1000.0 { "name them x_m, y_m, z_m, or convert them to mm" } else { "convert them to mm" }
            ),
        });
    }
    let has = |u: Unit| inputs.iter().any(|i| i.unit == u && i.approach_of.is_none() && !i.observed);
    let mut hypotheses: Vec<(Unit, f64, String)> = Vec::new();
    if has(Unit::Angle) {
        hypotheses.push((
            Unit::Angle,
            180.0 / std::f64::consts::PI,
            "the angle columns hold radians where they say degrees (name them _rad)".into(),
        ));
        hypotheses.push((
            Unit::Angle,
            std::f64::consts::PI / 180.0,
            "the angle columns hold degrees where they say radians (name them _deg)".into(),
        ));
    }
    if has(Unit::Length) {
        for (f, what) in LENGTH_FACTORS {
            hypotheses.push((Unit::Length, f, format!("the length inputs hold {what} where they say mm")));
        }
    }
    let best = hypotheses
        .iter()
        .filter_map(|(u, f, what)| compare(&tool_points(&*mech, &inputs, data, &rows, Some((*u, *f)))).map(|c| (c.0, what)))
        .min_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((rms, what)) = best {
        if rms < 0.2 * stated && stated > 5.0 {
            return Err(IoError::Invalid {
                path: data.path.clone(),
                message: format!(
                    "the joint values fit the nominal model far better in another unit: {what} (distances between poses {rms:.3} mm RMS from the model's, against {stated:.3} mm as stated)"
                ),
            });
        }
    }
    Ok(())
}

/// The centre of every seat of `data` under `mech` (`None` for a seat without rows): the linear
/// pivot calibration `R_i·t − c_s = −p_i` over every seat row (the tool point `t` the data find,
/// so a model without the ball's offset still places its seats), or the mean of the tool points
/// when the rows' orientations do not determine `t`.
fn seat_centres(mech: &dyn crate::Mechanism, data: &DataSet) -> Vec<Option<nalgebra::Vector3<f64>>> {
    use crate::measure::Observation;
    use nalgebra::{DMatrix, DVector, Vector3};
    let rows: Vec<(usize, crate::se3::Pose)> = data
        .measurements
        .iter()
        .filter_map(|m| match m.obs {
            Observation::Seat(k) => mech.forward(&m.q).ok().map(|p| (k, p)),
            _ => None,
        })
        .collect();
    let n = rows.iter().map(|r| r.0 + 1).max().unwrap_or(0);
    let mean = |k: usize| {
        let p: Vec<Vector3<f64>> = rows.iter().filter(|r| r.0 == k).map(|r| r.1.translation.vector).collect();
        (!p.is_empty()).then(|| p.iter().sum::<Vector3<f64>>() / p.len() as f64)
    };
    let (mut a, mut b) = (
        DMatrix::<f64>::zeros(3 * rows.len(), 3 + 3 * n),
        DVector::<f64>::zeros(3 * rows.len()),
    );
    for (i, (k, pose)) in rows.iter().enumerate() {
        let r = pose.rotation.to_rotation_matrix();
        for u in 0..3 {
            for v in 0..3 {
                a[(3 * i + u, v)] = r[(u, v)];
            }
            a[(3 * i + u, 3 + 3 * k + u)] = -1.0;
            b[3 * i + u] = -pose.translation.vector[u];
        }
    }
    let svd = a.svd(true, true);
    let (hi, lo) = (svd.singular_values.max(), svd.singular_values.min());
    match (rows.len() >= 4 && lo > 1e-3 * hi).then(|| svd.solve(&b, 1e-12).ok()).flatten() {
        Some(x) => (0..n)
            .map(|k| {
                rows.iter()
                    .any(|r| r.0 == k)
                    .then(|| Vector3::new(x[3 + 3 * k], x[4 + 3 * k], x[5 + 3 * k]))
            })
            .collect(),
        None => (0..n).map(mean).collect(),
    }
}

/// Known distances between seats against the nominal model's distance between the seats'
/// centres (each placed by the pivot calibration of its rows, the tool point found from them):
/// a distance about 1000× or 25.4× off is an error naming the unit; one outside half to twice the
/// nominal one, by more than twice the model's length tolerance, is an error naming the likely
/// cause (seats paired across placements, wrong seat numbers) and the pair the nominal model puts
/// at that distance, if one; outside 0.8–1.25× (by as much) it is a warning, returned as lines.
pub fn plausible_seat_distances(
    model: &ModelFile,
    data: &DataSet,
    distances: &[crate::instrument::SeatDistance],
) -> Result<Vec<String>, IoError> {
    let mut warnings = Vec::new();
    if distances.is_empty() {
        return Ok(warnings);
    }
    let mech = model.build();
    let centres = seat_centres(&*mech, data);
    let centre = |k: usize| centres.get(k).copied().flatten();
    let margin = 2.0 * model.tolerances.length_mm;
    for d in distances {
        let (Some(a), Some(b)) = (centre(d.a), centre(d.b)) else { continue };
        let nominal = (a - b).norm();
        if nominal < 1.0 {
            continue;
        }
        let ratio = nominal / d.length;
        let given = format!("--seat-distance {}:{}:{}", d.a, d.b, d.length);
        if let Some((f, what)) = length_factor(ratio) {
            return Err(IoError::Invalid {
                path: data.path.clone(),
                message: format!(
                    "{given}: the nominal model puts seats {} and {} {nominal:.1} mm apart, {f:.4}× the stated {} mm: {what} for mm? (give it in mm: {}:{}:{:.4})",
                    d.a, d.b, d.length, d.a, d.b, d.length * f
                ),
            });
        }
        if (nominal - d.length).abs() <= margin || (0.8..=1.25).contains(&ratio) {
            continue;
        }
        // The pair of seats the nominal model puts nearest the stated distance, if near it.
        let mut pairs = Vec::new();
        for i in 0..centres.len() {
            for j in i + 1..centres.len() {
                if let (Some(p), Some(q)) = (centre(i), centre(j)) {
                    pairs.push((i, j, (p - q).norm()));
                }
            }
        }
        let nearest = pairs
            .iter()
            .filter(|(i, j, _)| (*i, *j) != (d.a.min(d.b), d.a.max(d.b)))
            .min_by(|x, y| (x.2 - d.length).abs().total_cmp(&(y.2 - d.length).abs()))
            .filter(|(_, _, l)| (l - d.length).abs() <= margin.max(0.25 * d.length));
        let hint = nearest.map_or(String::new(), |(i, j, l)| {
            format!(
                " (it puts seats {i} and {j} {l:.1} mm apart: --seat-distance {i}:{j}:{}?)",
                d.length
            )
        });
        let line = format!(
            "{given}: the nominal model puts seats {} and {} {nominal:.1} mm apart, {ratio:.2}× the stated {} mm, more than the model's tolerances explain: seats paired across placements, or wrong seat numbers?{hint}",
            d.a, d.b, d.length
        );
        if (0.5..=2.0).contains(&ratio) {
            warnings.push(line);
        } else {
            return Err(IoError::Invalid {
                path: data.path.clone(),
                message: line,
            });
        }
    }
    Ok(warnings)
}

/// A stated noise the residual shows to be far too large: σ̂₀ below 0.1 while the data do hold
/// noise (a residual above 0.1 µm RMS: noise-free data pass), e.g. 5 mm stated for 5 µm. A
/// warning line with the figures; the fit itself stands.
pub fn stated_noise(sigma0: f64, noise_mm: f64) -> Option<String> {
    let residual = sigma0 * noise_mm;
    (sigma0 < 0.1 && residual > 1e-4).then(|| {
        format!(
            "σ̂₀ = {sigma0:.4}: the residual ({residual:.4} mm RMS) is a small fraction of the stated noise ({noise_mm} mm): the stated noise is far too large (mm where µm were meant?), so the standard deviations and the checks against the noise are too lax; state the instrument's noise"
        )
    })
}
