//! The rows of observed joints' readings ([`crate::model::Mechanism::observed_joints`]): each
//! reading minus the model's value, weighted by the encoder noise, beside the tracker's rows.
//! The model is evaluated once per measurement for both
//! ([`Mechanism::forward_and_observed`], [`Mechanism::forward_with_jacobian_and_observed`]).
use crate::error::{CalibError, KinError};
use crate::measure::{self, Measurement, Noise};
use crate::model::Mechanism;
use crate::params::Unit;
use crate::se3::Pose;
use nalgebra::{DMatrix, Matrix6xX};

/// A measurement's predicted pose and spatial Jacobian, with its weighted observed-joint rows:
/// the residual "reading − model" and the derivative of the model's values (`None` without
/// readings).
pub(crate) type Linearized = (Pose, Matrix6xX<f64>, Vec<f64>, Option<DMatrix<f64>>);

/// Whether measurement `m`, number `i`, has readings of the observed joints `units`: none, or
/// one per joint (else an error naming them).
fn has_readings(i: usize, m: &Measurement, units: &[(String, Unit)]) -> Result<bool, CalibError> {
    if m.joints.is_empty() {
        return Ok(false);
    }
    if m.joints.len() != units.len() {
        return Err(CalibError::InvalidOption(format!(
            "pose {i}: {} observed-joint readings for the model's {} observed joints ({})",
            m.joints.len(),
            units.len(),
            units.iter().map(|u| u.0.as_str()).collect::<Vec<_>>().join(", ")
        )));
    }
    Ok(true)
}

/// The predicted pose of measurement `m`, number `i`, and its weighted observed-joint residual
/// rows (empty without readings).
pub(crate) fn evaluate<M: Mechanism + ?Sized>(
    model: &M,
    i: usize,
    m: &Measurement,
    units: &[(String, Unit)],
    noise: &Noise,
) -> Result<(Pose, Vec<f64>), CalibError> {
    let kin = |source| CalibError::Kinematics { pose: i, source };
    if !has_readings(i, m, units)? {
        return Ok((model.forward(&m.q).map_err(kin)?, Vec::new()));
    }
    let (pose, values) = model.forward_and_observed(&m.q).map_err(kin)?;
    Ok((pose, weighted_residual(i, m, units, noise, &values)?))
}

/// [`Linearized`] of measurement `m`, number `i`, the forward kinematics started from `near`
/// when given: a kinematic failure or a non-finite Jacobian is [`CalibError::Kinematics`].
pub(crate) fn linearize<M: Mechanism + ?Sized>(
    model: &M,
    i: usize,
    m: &Measurement,
    units: &[(String, Unit)],
    noise: &Noise,
    near: Option<&Pose>,
) -> Result<Linearized, CalibError> {
    if !has_readings(i, m, units)? {
        let (pose, jac) = super::spatial_jacobian_near(model, i, m, near)?;
        return Ok((pose, jac, Vec::new(), None));
    }
    let kin = |source| CalibError::Kinematics { pose: i, source };
    let (pose, jac, values, mut rows) = model.forward_with_jacobian_and_observed(&m.q, near).map_err(kin)?;
    super::check_jacobian(i, &jac)?;
    let r = weighted_residual(i, m, units, noise, &values)?;
    for (k, w) in measure::joint_weights(units, noise).iter().enumerate() {
        rows.row_mut(k).scale_mut(*w);
    }
    if rows.iter().any(|v| !v.is_finite()) {
        return Err(kin(KinError::NonFinite("the observed joints' Jacobian".into())));
    }
    Ok((pose, jac, r, Some(rows)))
}

/// Readings minus the model's `values`, each divided by its encoder's σ.
fn weighted_residual(i: usize, m: &Measurement, units: &[(String, Unit)], noise: &Noise, values: &[f64]) -> Result<Vec<f64>, CalibError> {
    let r: Vec<f64> = m
        .joints
        .iter()
        .zip(values)
        .zip(units)
        .zip(measure::joint_weights(units, noise))
        .map(|(((reading, value), (_, unit)), w)| {
            let d = reading - value;
            let d = if *unit == Unit::Angle { crate::se3::wrap_angle(d) } else { d };
            d * w
        })
        .collect();
    if r.iter().any(|v| !v.is_finite()) {
        let source = KinError::NonFinite("an observed joint's residual (check its reading)".into());
        return Err(CalibError::Kinematics { pose: i, source });
    }
    Ok(r)
}
