//! Touches on unknown planes give no length ([`crate::instrument::touch::no_length`]): on a
//! machine whose inputs all turn, scaling the machine and its probe offset together moves every
//! touch onto planes that fit as well (each plane's offset absorbs it), so the fit cannot tell
//! the scale and drifts along it. [`scale_gauge`] finds the parameter that holds the scale at
//! the model's drawing: the scale direction `v` solves `J·v ≈ p` (the tool points' Jacobian
//! over the free parameters at the data's configurations against the points themselves, what
//! scaling about the base moves them by), and the free length parameter that carries most of
//! it (`|v_k|·‖J_k‖`, lengths only) is held, so the calibrated machine keeps that length of its drawing.
use crate::measure::{self, Measurement, Observation};
use crate::model::framed::TOOL_TRANSLATION;
use crate::model::Mechanism;
use nalgebra::{DMatrix, DVector};

/// Relative residual of `J·v ≈ p` below which the free parameters can scale the machine.
const SCALES: f64 = 1e-6;

/// The index (into `free`) of the parameter to hold so that `model` keeps its scale on
/// `measurements` (module docs), or `None` when the free parameters cannot scale the machine
/// (the scale is seen) or the tool points cannot be computed. `framed_params`: the columns of
/// `free` below it are the framed machine's (the rest, the artifacts', are left out).
pub fn scale_gauge(model: &dyn Mechanism, measurements: &[Measurement], free: &[usize], framed_params: usize) -> Option<usize> {
    let columns: Vec<usize> = (0..free.len()).filter(|&k| free[k] < framed_params).collect();
    if columns.is_empty() {
        return None;
    }
    let rows = 3 * measurements.len();
    let mut a = DMatrix::zeros(rows, columns.len());
    let mut b = DVector::zeros(rows);
    for (i, m) in measurements.iter().enumerate() {
        let (pose, jac) = model.forward_with_jacobian(&m.q).ok()?;
        let p = pose.translation.vector;
        let j = measure::residual_jacobian(&Observation::Position(p), &pose, &jac);
        for (c, &k) in columns.iter().enumerate() {
            for r in 0..3 {
                a[(3 * i + r, c)] = j[(r, free[k])];
            }
        }
        b.rows_mut(3 * i, 3).copy_from(&p);
    }
    let v = a.clone().svd(true, true).solve(&b, 1e-12).ok()?;
    let misfit = (&a * &v - &b).norm() / b.norm().max(f64::MIN_POSITIVE);
    if misfit > SCALES {
        return None;
    }
    // A length of the machine: the tool offset scales too, but holding it would hold the
    // probe, not the machine; angles do not scale.
    let params = model.params();
    (0..columns.len())
        .filter(|&c| !TOOL_TRANSLATION.contains(&free[columns[c]]))
        .filter(|&c| params.get(free[columns[c]]).is_some_and(|p| p.unit == crate::params::Unit::Length))
        .map(|c| (columns[c], v[c].abs() * a.column(c).norm()))
        .filter(|(_, w)| w.is_finite() && *w > 0.0)
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .map(|(k, _)| k)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::framed::{Framed, FRAME_PARAMS};
    use crate::params::Unit;
    use crate::se3::{pose_from_parts, Pose};
    use nalgebra::Vector3;
    use rand::SeedableRng;

    /// On the IRB 120 with every length free the scale direction exists and a length is held;
    /// with the lengths fixed (only angles and the tool offset free) nothing can scale the arm.
    #[test]
    fn a_length_holds_the_scale_only_when_the_free_parameters_can_scale() {
        let arm = crate::model::builtin::irb120();
        let inputs = crate::io::builtin::model_file("irb120").unwrap().inputs();
        let model = Framed::new(
            Box::new(arm) as Box<dyn Mechanism>,
            Pose::identity(),
            pose_from_parts(Vector3::new(15.0, -10.0, 120.0), Vector3::zeros()),
        );
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let qs = crate::simulate::random_configurations(&model, &inputs, 40, &mut rng).unwrap();
        let rows: Vec<Measurement> = qs
            .into_iter()
            .map(|q| Measurement {
                q,
                obs: Observation::Seat(0),
                joints: Vec::new(),
            })
            .collect();
        let params = model.params();
        let mut free: Vec<usize> = TOOL_TRANSLATION.collect();
        free.extend(FRAME_PARAMS..params.len());
        let k = scale_gauge(&model, &rows, &free, params.len()).expect("every length free: the arm can scale");
        assert_eq!(params[free[k]].unit, Unit::Length, "{}", params[free[k]].name);
        let angles: Vec<usize> = free
            .iter()
            .copied()
            .filter(|&c| TOOL_TRANSLATION.contains(&c) || params[c].unit != Unit::Length)
            .collect();
        assert_eq!(scale_gauge(&model, &rows, &angles, params.len()), None);
    }
}
