//! The rows of observed joints' readings ([`crate::model::Mechanism::observed_joints`]): each
//! reading minus the model's value, weighted by the encoder noise, beside the tracker's rows.
use crate::error::{CalibError, KinError};
use crate::measure::{self, Measurement, Noise};
use crate::model::Mechanism;
use nalgebra::DMatrix;

/// The observed-joint rows of measurement `m`, number `i` (none when it has no readings): the
/// weighted residual "reading − model" and, with `jacobian`, the weighted derivative of the
/// model's values (the rows of the prediction's derivative, as for the pose rows). `units` are
/// the mechanism's [`Mechanism::observed_joints`].
pub(crate) fn joint_rows<M: Mechanism + ?Sized>(
    model: &M,
    i: usize,
    m: &Measurement,
    units: &[(String, crate::params::Unit)],
    noise: &Noise,
    jacobian: bool,
) -> Result<(Vec<f64>, Option<DMatrix<f64>>), CalibError> {
    if m.joints.is_empty() {
        return Ok((Vec::new(), None));
    }
    if m.joints.len() != units.len() {
        return Err(CalibError::InvalidOption(format!(
            "pose {i}: {} observed-joint readings for the model's {} observed joints ({})",
            m.joints.len(),
            units.len(),
            units.iter().map(|u| u.0.as_str()).collect::<Vec<_>>().join(", ")
        )));
    }
    let kin = |source| CalibError::Kinematics { pose: i, source };
    let (values, jac) = if jacobian {
        let (v, j) = model.observed_joints_with_jacobian(&m.q).map_err(kin)?;
        (v, Some(j))
    } else {
        (model.observed_joint_values(&m.q).map_err(kin)?, None)
    };
    let w = measure::joint_weights(units, noise);
    let r: Vec<f64> = m
        .joints
        .iter()
        .zip(&values)
        .zip(units)
        .zip(&w)
        .map(|(((reading, value), (_, unit)), w)| {
            let d = reading - value;
            let d = if *unit == crate::params::Unit::Angle {
                crate::se3::wrap_angle(d)
            } else {
                d
            };
            d * w
        })
        .collect();
    if r.iter().any(|v| !v.is_finite()) {
        return Err(kin(KinError::NonFinite("an observed joint's residual (check its reading)".into())));
    }
    let jac = jac.map(|mut j| {
        for (k, wk) in w.iter().enumerate() {
            j.row_mut(k).scale_mut(*wk);
        }
        j
    });
    if jac.as_ref().is_some_and(|j| j.iter().any(|v| !v.is_finite())) {
        return Err(kin(KinError::NonFinite("the observed joints' Jacobian".into())));
    }
    Ok((r, jac))
}
