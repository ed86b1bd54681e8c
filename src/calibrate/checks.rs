//! Plausibility checks of the data against the model before anything is fitted: mistakes a
//! file can hold that would otherwise come out as a wrong calibration.
use crate::io::data_file::DataSet;
use crate::io::model_file::ModelFile;
use crate::io::IoError;
use crate::params::Unit;
use std::f64::consts::PI;

/// Angle columns whose every value, read in degrees, stays within ±π (what radians in a degree
/// column give) while the joint's limits allow far more, are almost certainly in the wrong unit.
pub fn plausible_angles(model: &ModelFile, data: &DataSet) -> Result<(), IoError> {
    if data.measurements.len() < 10 {
        return Ok(());
    }
    let inputs = model.inputs();
    let suspicious: Vec<&str> = inputs
        .iter()
        .enumerate()
        .filter(|(_, i)| i.unit == Unit::Angle)
        .filter(|(_, i)| i.limits.is_none_or(|(lo, hi)| hi - lo > 4.0 * PI.to_radians()))
        .filter(|(k, _)| {
            let max = data.measurements.iter().map(|m| m.q[*k].abs()).fold(0.0, f64::max);
            max > 0.0 && max <= PI.to_radians() * 1.0001
        })
        .map(|(_, i)| i.name.as_str())
        .collect();
    if suspicious.len() >= 2 && suspicious.len() * 2 >= inputs.iter().filter(|i| i.unit == Unit::Angle).count() {
        return Err(IoError::Invalid {
            path: data.path.clone(),
            message: format!(
                "the angle columns {} never leave ±3.1416 degrees: they look like radians; name them {}_rad (or convert them to degrees)",
                suspicious.join(", "),
                suspicious[0]
            ),
        });
    }
    Ok(())
}
