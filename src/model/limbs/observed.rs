//! The closure's derivatives at a forward solution, and the observed joints
//! ([`super::JointRole::Observed`]): passive joints the closure solves whose sensors are read as
//! observations. By the implicit-function theorem `dz = −F_z⁺·F_θ`: its first six rows are the
//! platform's (the identification Jacobian), the observed joints' rows are theirs.
use super::LimbMechanism;
use crate::error::KinError;
use crate::model::chain::JointKind;
use crate::model::{check_inputs, Mechanism};
use crate::params::Unit;
use crate::se3::Pose;
use nalgebra::{DMatrix, Matrix6xX};

/// A forward solution (platform pose, passive joints) with the closure's derivatives there with
/// respect to the unknowns (`F_z`) and the error parameters (`F_θ`).
type ClosureAt = (Pose, Vec<f64>, DMatrix<f64>, DMatrix<f64>);

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

    /// The observed joints' values among the passive joints' `passive`.
    pub(super) fn observed_of(&self, passive: &[f64]) -> Vec<f64> {
        self.observed.iter().map(|&k| passive[k]).collect()
    }

    /// The observed joints' values at inputs `q`.
    pub(super) fn observed_values(&self, q: &[f64]) -> Result<Vec<f64>, KinError> {
        if self.observed.is_empty() {
            return Ok(Vec::new());
        }
        Ok(self.observed_of(&self.forward_full(q)?.1))
    }

    /// The observed joints' values at inputs `q` and their parameter Jacobian (rows: observed
    /// joints; columns: error parameters).
    pub(super) fn observed_with_jacobian(&self, q: &[f64]) -> Result<(Vec<f64>, DMatrix<f64>), KinError> {
        if self.observed.is_empty() {
            return Ok((Vec::new(), DMatrix::zeros(0, self.n_params())));
        }
        let (_, passive, fz, fp) = self.linearized(q)?;
        Ok((self.observed_of(&passive), self.observed_rows(&fz, &fp)?))
    }

    /// The forward solution at inputs `q` (platform pose, passive joints) and the closure's
    /// derivatives there with respect to the unknowns (`F_z`) and the error parameters (`F_θ`).
    pub(super) fn linearized(&self, q: &[f64]) -> Result<ClosureAt, KinError> {
        let (x, passive) = self.forward_full(q)?;
        let (fz, fp) = self.derivatives_at(q, &x, &passive);
        Ok((x, passive, fz, fp))
    }

    /// [`Mechanism::forward_with_jacobian_at`]: the platform rows at the forward solution
    /// `(x, passive)` of inputs `q` (solved again when `passive` has the wrong length).
    pub(super) fn jacobian_at(&self, q: &[f64], x: &Pose, passive: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        check_inputs(q, self.inputs.len())?;
        if passive.len() != self.passive.len() {
            return self.forward_with_jacobian(q);
        }
        let (fz, fp) = self.derivatives_at(q, x, passive);
        Ok((*x, self.platform_rows(&fz, &fp)?))
    }

    /// The closure's derivatives `F_z` and `F_θ` at the forward solution `(x, passive)` of inputs
    /// `q`.
    pub(super) fn derivatives_at(&self, q: &[f64], x: &Pose, passive: &[f64]) -> (DMatrix<f64>, DMatrix<f64>) {
        let joints = self.joints_of(q, passive);
        let (_, fz) = self.closure(x, &joints, true);
        let fp = self.closure_params(x, &joints);
        (fz, fp)
    }

    /// The platform's six rows of `dz = −F_z⁺·F_θ`: the spatial identification Jacobian.
    pub(super) fn platform_rows(&self, fz: &DMatrix<f64>, fp: &DMatrix<f64>) -> Result<Matrix6xX<f64>, KinError> {
        let singular = || KinError::Singular {
            what: "identification Jacobian of a limb mechanism".into(),
            condition: f64::INFINITY,
        };
        // With F_z square, the six rows of F_z⁻¹ from F_zᵀ·Y = [I₆; 0] (six solves instead of
        // one per parameter).
        let top = if let Some(top) = self.platform_jacobian_by_limbs(fz, fp) {
            top
        } else if fz.is_square() {
            let e = DMatrix::from_fn(fz.nrows(), 6, |r, c| if r == c { 1.0 } else { 0.0 });
            let y = fz
                .transpose()
                .lu()
                .solve(&e)
                .filter(|y| y.iter().all(|v| v.is_finite()))
                .ok_or_else(singular)?;
            -(y.transpose() * fp)
        } else if fz.iter().chain(fp.iter()).any(|v| !v.is_finite()) {
            // (nalgebra's SVD does not return on non-finite input.)
            return Err(singular());
        } else {
            let dz = fz.clone().svd(true, true).solve(&(-fp), 0.0).map_err(|_| singular())?;
            dz.rows(0, 6).into_owned()
        };
        let mut j = Matrix6xX::zeros(top.ncols());
        j.copy_from(&top);
        Ok(j)
    }

    /// The observed joints' rows of `dz = −F_z⁺·F_θ` (none without observed joints).
    pub(super) fn observed_rows(&self, fz: &DMatrix<f64>, fp: &DMatrix<f64>) -> Result<DMatrix<f64>, KinError> {
        if self.observed.is_empty() {
            return Ok(DMatrix::zeros(0, fp.ncols()));
        }
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
        Ok(-(y.transpose() * fp))
    }
}
