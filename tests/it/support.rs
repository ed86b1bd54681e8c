//! Helpers shared by the test modules: finite-difference Jacobians and their step sizes; the
//! targets file of a workflow test.
use kinecal::io::data_file::{read_data, write_data, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::measure::{Measurement, Observation};
use kinecal::model::Mechanism;
use kinecal::se3;
use nalgebra::{DMatrix, DVector};
use std::path::Path;

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

/// Step sizes by unit: 1e-5 rad, 1e-3 mm. (The central differences' truncation error is then
/// ~1e-10 relative; their round-off, the forward kinematics' 1e-11 mm tolerance over the step
/// amplified by a closed loop's conditioning, ~1e-7: at 1e-6 rad / 1e-4 mm a linear-delta
/// configuration reached 1.2e-6.)
pub fn steps<M: Mechanism + ?Sized>(m: &M) -> Vec<f64> {
    m.params()
        .iter()
        .map(|p| if p.unit == kinecal::params::Unit::Angle { 1e-5 } else { 1e-3 })
        .collect()
}

/// Targets where the nominal model puts the validation commands (no input columns).
pub fn nominal_targets(d: &Path, model: &ModelFile) -> Vec<se3::Pose> {
    let nominal = model.build();
    let val = read_data(&d.join("valid.csv"), &model.data_columns(), InputColumns::Required).unwrap();
    let targets: Vec<se3::Pose> = val.measurements.iter().map(|m| nominal.forward(&m.q).unwrap()).collect();
    let rows: Vec<Measurement> = targets
        .iter()
        .map(|t| Measurement {
            joints: Vec::new(),
            q: vec![],
            obs: Observation::Pose(*t),
        })
        .collect();
    write_data(&d.join("targets.csv"), &model.inputs(), &val.ids, &rows, None).unwrap();
    targets
}
