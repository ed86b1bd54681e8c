//! Each measurement kind's residual against its own stated noise ([`KindResidual`]): with rows of
//! several kinds in one fit (tracker points and seats, distances and seats), σ̂₀ mixes them; the
//! report gives each kind's RMS and its ratio to that kind's σ, and the verdict names a kind far
//! above its own noise while the others are not ([`CalibrationReport::judge_kinds`]).
use super::{CalibrationReport, SIGMA0_WARN};
use crate::measure::{residual, Measurement, Noise, RowKind};
use crate::model::Mechanism;
use serde::Serialize;

/// One kind's residual after the fit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KindResidual {
    /// The kind ([`RowKind::name`]).
    pub kind: String,
    /// Its rows (measurements).
    pub rows: usize,
    /// RMS of its residual components (mm: per axis for tracker positions and seats, along the
    /// bar for distances; a tracker pose's orientation rows left out).
    pub rms_mm: f64,
    /// The σ it was weighted by ([`Noise::sigma`]).
    pub sigma_mm: f64,
    /// `rms_mm / sigma_mm`: about 1 when the kind's stated noise is right (σ̂ of that kind).
    pub ratio: f64,
}

impl KindResidual {
    /// What its residual measures, e.g. `seat spread (per axis)`, `bar length`.
    pub fn what(&self) -> &'static str {
        match RowKind::ALL.into_iter().find(|r| r.name() == self.kind) {
            Some(RowKind::Tracker) => "tracker position (per axis)",
            Some(RowKind::Seat) => "seat spread (per axis)",
            Some(RowKind::Distance) => "bar length",
            Some(RowKind::Probe) => "touch distance (along the surface's normal)",
            None => "residual",
        }
    }

    /// Whether it is an instrument's kind (not a tracker's).
    pub fn instrument(&self) -> bool {
        self.kind != RowKind::Tracker.name()
    }
}

/// Each kind's residual of `model` at `data` (as the fit used them), in [`RowKind::ALL`] order;
/// kinds without rows left out, rows the model cannot evaluate skipped.
pub fn kind_residuals(model: &dyn Mechanism, data: &[Measurement], noise: &Noise) -> Vec<KindResidual> {
    RowKind::ALL
        .into_iter()
        .filter_map(|kind| {
            let (mut sum, mut n, mut rows) = (0.0, 0usize, 0usize);
            for m in data.iter().filter(|m| RowKind::of(&m.obs) == Some(kind)) {
                let Ok(pose) = model.forward(&m.q) else { continue };
                let r = residual(&m.obs, &pose);
                let lin = match m.obs {
                    crate::measure::Observation::Pose(_) => &r[..3],
                    _ => &r[..],
                };
                sum += lin.iter().map(|v| v * v).sum::<f64>();
                n += lin.len();
                rows += 1;
            }
            (rows > 0).then(|| {
                let rms_mm = (sum / n as f64).sqrt();
                let sigma_mm = noise.sigma(kind);
                KindResidual {
                    kind: kind.name().into(),
                    rows,
                    rms_mm,
                    sigma_mm,
                    ratio: rms_mm / sigma_mm,
                }
            })
        })
        .collect()
}

impl CalibrationReport {
    /// With rows of several kinds: a warning naming each kind whose residual is more than
    /// [`SIGMA0_WARN`] times its own stated σ (its noise is optimistic, or that instrument's
    /// rows disagree with the others: a seat that moved, a wrong ballbar length). Never a
    /// failure: the verdict on the residual as a whole is [`CalibrationReport::assess`]'s.
    pub fn judge_kinds(&mut self, kinds: Vec<KindResidual>) {
        if kinds.len() > 1 {
            for k in kinds.iter().filter(|k| k.ratio > SIGMA0_WARN) {
                self.warn(format!(
                    "the {} rows' residual is {:.1}× their stated noise ({:.4} mm RMS, σ {:.4} mm) while the fit mixes {} kinds: that instrument's noise is optimistic (state it: [noise] {} in the model file, --kind-noise), or its rows disagree with the others (a seat or pivot that moved, a wrong length)",
                    k.kind,
                    k.ratio,
                    k.rms_mm,
                    k.sigma_mm,
                    kinds.len(),
                    RowKind::ALL.iter().find(|r| r.name() == k.kind).map_or("position", |r| r.noise_key()),
                ));
            }
        }
        self.kinds = kinds;
    }
}
