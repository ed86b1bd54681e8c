//! Helpers shared by the test modules: finite-difference Jacobians and their step sizes.
use kinecal::model::Mechanism;
use kinecal::se3;
use nalgebra::{DMatrix, DVector};

/// Central finite differences of the spatial identification Jacobian: retract by ±h along each
/// coordinate and take log(T(+h)·T(−h)⁻¹)/(2h).
pub fn fd_jacobian<M: Mechanism + Clone>(m: &M, q: &[f64], h: &[f64]) -> DMatrix<f64> {
    let p = m.n_params();
    let mut out = DMatrix::zeros(6, p);
    for k in 0..p {
        let mut e = DVector::zeros(p);
        e[k] = h[k];
        let mut plus = m.clone();
        plus.retract(&e);
        let mut minus = m.clone();
        minus.retract(&(-e));
        let d = se3::log(&(plus.forward(q).unwrap() * minus.forward(q).unwrap().inverse())) / (2.0 * h[k]);
        out.set_column(k, &d);
    }
    out
}

/// Step sizes by unit: 1e-6 rad, 1e-4 mm.
pub fn steps<M: Mechanism + ?Sized>(m: &M) -> Vec<f64> {
    m.params()
        .iter()
        .map(|p| if p.unit == kinecal::params::Unit::Angle { 1e-6 } else { 1e-4 })
        .collect()
}
