//! Observed joints ([`super::JointRole::Observed`]): passive joints the closure solves whose
//! sensors are read as observations. Their values come with the forward kinematics; their
//! derivative with respect to the error parameters is the implicit-function theorem's
//! `dz = −F_z⁺·F_θ` at their rows (the platform's rows are the identification Jacobian).
use super::LimbMechanism;
use crate::error::KinError;
use crate::model::chain::JointKind;
use crate::params::Unit;
use nalgebra::DMatrix;

impl LimbMechanism {
    /// Names and units of the observed joints, in limb order.
    pub(super) fn observed_names(&self) -> Vec<(String, Unit)> {
        self.observed
            .iter()
            .map(|&k| {
                let (i, j) = self.passive[k];
                let jt = &self.limbs[i].chain.joints()[j];
                let unit = match jt.kind {
                    JointKind::Revolute => Unit::Angle,
                    JointKind::Prismatic => Unit::Length,
                };
                (jt.name.clone(), unit)
            })
            .collect()
    }

    /// The observed joints' values at inputs `q`.
    pub(super) fn observed_values(&self, q: &[f64]) -> Result<Vec<f64>, KinError> {
        if self.observed.is_empty() {
            return Ok(Vec::new());
        }
        let (_, passive) = self.forward_full(q)?;
        Ok(self.observed.iter().map(|&k| passive[k]).collect())
    }

    /// The observed joints' values at inputs `q` and their parameter Jacobian (rows: observed
    /// joints; columns: error parameters).
    pub(super) fn observed_with_jacobian(&self, q: &[f64]) -> Result<(Vec<f64>, DMatrix<f64>), KinError> {
        use crate::model::Mechanism;
        if self.observed.is_empty() {
            return Ok((Vec::new(), DMatrix::zeros(0, self.n_params())));
        }
        let (x, passive) = self.forward_full(q)?;
        let joints = self.joints_of(q, &passive);
        let (_, fz) = self.closure(&x, &joints, true);
        let fp = self.closure_params(&x, &joints);
        let singular = || KinError::Singular {
            what: "observed-joint Jacobian of a limb mechanism".into(),
            condition: f64::INFINITY,
        };
        if fz.iter().chain(fp.iter()).any(|v| !v.is_finite()) {
            return Err(singular());
        }
        // Rows 6 + k of F_z⁺ (F_z square: from F_zᵀ·Y = E, one solve per observed joint).
        let e = DMatrix::from_fn(
            fz.ncols(),
            self.observed.len(),
            |r, c| if r == 6 + self.observed[c] { 1.0 } else { 0.0 },
        );
        let y = if fz.is_square() {
            fz.transpose().lu().solve(&e).ok_or_else(singular)?
        } else {
            let pinv = fz.clone().pseudo_inverse(1e-14).map_err(|_| singular())?;
            pinv.transpose() * e
        };
        if y.iter().any(|v| !v.is_finite()) {
            return Err(singular());
        }
        let jac = -(y.transpose() * fp);
        Ok((self.observed.iter().map(|&k| passive[k]).collect(), jac))
    }
}
