//! Held-out instrument data in the report: a validation file's own artifacts (seats, pivots,
//! spheres, planes, datum cubes), each placed by its own rows with the model fixed
//! ([`crate::instrument::held_out`]), under the nominal and the calibrated model.
use crate::instrument::{HeldOut, PointKind};
use serde::Serialize;

/// A validation file of instrument rows judged in the instrument's terms, before and after.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct HeldOutPlacements {
    /// Validation data file (for display).
    pub source: String,
    /// Rows judged (every artifact).
    pub rows: usize,
    /// The nominal model's figures: the drawing with the tool point found from the
    /// identification data, the model the identification set's "before" is the error of.
    pub nominal: HeldOut,
    /// The calibrated model's figures (the model file `identify` writes: `kinecal validate` of
    /// that file on the same data gives them).
    pub calibrated: HeldOut,
    /// RMS over every row's residual under the nominal model (mm, [`HeldOut::rms_mm`]).
    pub before_rms_mm: f64,
    /// The same under the calibrated model (mm).
    pub after_rms_mm: f64,
}

/// Known distances listed one per line at most this many times (the JSON has every one).
const SHOWN_DISTANCES: usize = 10;

impl HeldOutPlacements {
    /// The figures of `nominal` and `calibrated` on the rows of `source`.
    pub fn new(source: impl Into<String>, nominal: HeldOut, calibrated: HeldOut) -> HeldOutPlacements {
        HeldOutPlacements {
            source: source.into(),
            rows: calibrated.rows(),
            before_rms_mm: nominal.rms_mm().unwrap_or(0.0),
            after_rms_mm: calibrated.rms_mm().unwrap_or(0.0),
            nominal,
            calibrated,
        }
    }

    /// RMS of the known seat distances' errors, nominal and calibrated (mm); `None` without
    /// known distances.
    pub fn distance_error_rms_mm(&self) -> Option<(f64, f64)> {
        Some((self.nominal.distance_error_rms_mm()?, self.calibrated.distance_error_rms_mm()?))
    }

    /// Each kind of artifact judged: (kind, what its residual is, artifacts, rows, nominal RMS,
    /// calibrated RMS), mm.
    pub fn kinds(&self) -> Vec<(PointKind, &'static str, usize, usize, f64, f64)> {
        [
            PointKind::Seat,
            PointKind::Pivot,
            PointKind::Sphere,
            PointKind::Plane,
            PointKind::Cube,
        ]
        .into_iter()
        .filter_map(|kind| {
            let (n, rows, before) = self.nominal.kind_rms_mm(kind)?;
            let (_, _, after) = self.calibrated.kind_rms_mm(kind)?;
            Some((kind, residual_of(kind), n, rows, before, after))
        })
        .collect()
    }

    /// The figures as lines of text (what `kinecal identify` prints): a heading, one line per
    /// kind of artifact, one per known distance (at most ten).
    pub fn lines(&self) -> Vec<String> {
        let mut out = vec![format!(
            "held-out data {} ({} rows; each artifact placed by its own rows, the model fixed), nominal → calibrated:",
            self.source, self.rows
        )];
        let kinds = self.kinds();
        if kinds.len() > 1 {
            out.push(format!("  every row: {:.4} → {:.4} mm RMS", self.before_rms_mm, self.after_rms_mm));
        }
        for (kind, what, n, rows, before, after) in kinds {
            let plural = if n == 1 { "" } else { "s" };
            out.push(format!(
                "  {n} {}{plural} ({rows} rows): {what} {before:.4} → {after:.4} mm RMS",
                kind.name()
            ));
        }
        let pairs = self.nominal.distances.iter().zip(&self.calibrated.distances);
        for ((a, b, known, before), (.., after)) in pairs.clone().take(SHOWN_DISTANCES) {
            out.push(format!(
                "  seats {a}–{b}, known {known:.4} mm apart: error {before:+.4} → {after:+.4} mm"
            ));
        }
        if self.nominal.distances.len() > SHOWN_DISTANCES {
            let (b, a) = self.distance_error_rms_mm().unwrap_or_default();
            out.push(format!(
                "  … {} known distances in all: error {b:.4} → {a:.4} mm RMS",
                self.nominal.distances.len()
            ));
        }
        out
    }
}

/// What a kind's residual is, in words.
pub fn residual_of(kind: PointKind) -> &'static str {
    match kind {
        PointKind::Seat => "spread of the tool points about their seat's mean",
        PointKind::Pivot => "measured − modelled length",
        PointKind::Sphere => "measured − modelled distance from the sphere's centre",
        PointKind::Plane => "probe centres from their best plane",
        PointKind::Cube => "probe centres from the placed cube's faces",
    }
}
