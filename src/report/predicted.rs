//! The report's map of the accuracy the calibration predicts ([`crate::predict`]): the predicted
//! position σ over the workspace, beside the maps of the measured errors.
use super::plot;
use serde::Serialize;
use std::fmt::Write as _;

/// The predicted position σ at measured configurations and at configurations drawn over the
/// workspace (measurement frame).
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PredictedMap {
    /// Predicted tool positions (mm).
    pub positions: Vec<[f64; 3]>,
    /// Predicted position σ there (mm, RMS 3-D error, [`crate::predict::PoseAccuracy::position_mm`]).
    pub sigma_mm: Vec<f64>,
    /// Whether each is a measured configuration (else drawn over the workspace).
    pub measured: Vec<bool>,
    /// What one measurement's noise adds (mm, `√3·σ_position`).
    pub noise_mm: f64,
}

impl PredictedMap {
    /// The map as HTML: x–y and x–z projections coloured by the predicted σ.
    pub fn html(&self, h: &mut String) -> Result<(), String> {
        let (meas, drawn): (Vec<f64>, Vec<f64>) = (self.values(true), self.values(false));
        let max = |v: &[f64]| v.iter().copied().fold(0.0, f64::max);
        let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len().max(1) as f64).sqrt();
        h.push_str("<h2 id=\"predicted\">Predicted accuracy over the workspace</h2>\n");
        let _ = write!(
            h,
            "<p class=\"muted\">The position uncertainty this calibration leaves (its parameters' covariance carried to each pose: RMS 3-D error, mm), at the measured poses (open squares) and at {} configurations drawn over the workspace (filled circles): where it is large, the calibration is not to be trusted and more poses should be measured. Measured poses: RMS {:.4} mm, max {:.4} mm; drawn: RMS {:.4} mm, max {:.4} mm. A measurement adds its noise, {:.4} mm.</p><div class=\"plots\">",
            drawn.len(),
            rms(&meas),
            max(&meas),
            rms(&drawn),
            max(&drawn),
            self.noise_mm
        );
        let axis = |k: usize| self.positions.iter().map(|p| p[k]).collect::<Vec<f64>>();
        for (b, label) in [(1, "y"), (2, "z")] {
            h.push_str(&plot::workspace_map(
                &format!("x–{label}: predicted position σ"),
                "x (mm)",
                &format!("{label} (mm)"),
                &axis(0),
                &axis(b),
                &self.sigma_mm,
                &self.measured,
                "● drawn over the workspace  □ measured",
            )?);
        }
        h.push_str("</div>\n");
        Ok(())
    }

    fn values(&self, measured: bool) -> Vec<f64> {
        self.sigma_mm
            .iter()
            .zip(&self.measured)
            .filter(|(_, m)| **m == measured)
            .map(|(s, _)| *s)
            .collect()
    }
}
