//! Kinds of measurement rows and the noise each one states ([`RowKind`], [`KindNoise`]): one fit
//! may hold rows of several kinds (a few tracker points and many seat rows, ballbar lengths and
//! seats), each weighted by its own σ and judged against it.
//!
//! Adding a kind: one variant of [`RowKind`] (its name, its `[noise]` key) and one field of
//! [`KindNoise`]; the model file's `[noise]` section, the command line's `--kind-noise` and the
//! report's per-kind residuals follow.
use super::{Observation, KNOWN_DISTANCE};
use serde::{Deserialize, Serialize};

/// What a measurement row is, as far as its noise goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
pub enum RowKind {
    /// A tracker's pose, position or reflector points (σ: [`super::Noise::position`] and
    /// [`super::Noise::orientation`]).
    Tracker,
    /// The tool point in a seat (σ of where the ball settles, per axis).
    Seat,
    /// A ballbar's or draw-wire's length (σ along the bar).
    Distance,
    /// A touch probe's touch on a sphere, a plane or a datum cube's face (σ along the surface's
    /// normal).
    Probe,
}

impl RowKind {
    /// Every kind, in report order.
    pub const ALL: [RowKind; 4] = [RowKind::Tracker, RowKind::Seat, RowKind::Distance, RowKind::Probe];

    /// The kind of an observation; `None` for a known distance between seats (a certified
    /// dimension, not a measurement).
    pub fn of(obs: &Observation) -> Option<RowKind> {
        match obs {
            Observation::Pose(_) | Observation::Position(_) | Observation::Points(_) => Some(RowKind::Tracker),
            Observation::Seat(_) => Some(RowKind::Seat),
            Observation::Distance { pivot: KNOWN_DISTANCE, .. } => None,
            Observation::Distance { .. } => Some(RowKind::Distance),
            Observation::Touch(_) => Some(RowKind::Probe),
        }
    }

    /// Its name in messages and reports: `tracker`, `seat`, `distance`, `probe`.
    pub fn name(self) -> &'static str {
        match self {
            RowKind::Tracker => "tracker",
            RowKind::Seat => "seat",
            RowKind::Distance => "distance",
            RowKind::Probe => "probe",
        }
    }

    /// Its key in a model file's `[noise]` section (in the file's length unit) and in
    /// `--kind-noise KIND=MM`: `position`, `seat`, `distance`, `probe`.
    pub fn noise_key(self) -> &'static str {
        match self {
            RowKind::Tracker => "position",
            RowKind::Seat => "seat",
            RowKind::Distance => "distance",
            RowKind::Probe => "probe",
        }
    }

    /// The kind of a `[noise]` key or a name ([`Self::noise_key`], [`Self::name`]).
    pub fn from_key(key: &str) -> Option<RowKind> {
        RowKind::ALL.into_iter().find(|k| k.noise_key() == key || k.name() == key)
    }
}

/// The σ (mm) each instrument kind states; `None`: the tracker's position noise
/// ([`super::Noise::position`]), which is what a data set of one kind was always weighted by.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct KindNoise {
    /// Seat rows (per axis).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seat: Option<f64>,
    /// Distance rows (along the bar).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distance: Option<f64>,
    /// Touch-probe rows (along the surface's normal).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub probe: Option<f64>,
}

impl KindNoise {
    /// The σ stated for `kind` (`None` for the tracker, whose σ is the position noise).
    pub fn get(&self, kind: RowKind) -> Option<f64> {
        match kind {
            RowKind::Tracker => None,
            RowKind::Seat => self.seat,
            RowKind::Distance => self.distance,
            RowKind::Probe => self.probe,
        }
    }

    /// The field of `kind` (`None` for the tracker).
    pub fn get_mut(&mut self, kind: RowKind) -> Option<&mut Option<f64>> {
        match kind {
            RowKind::Tracker => None,
            RowKind::Seat => Some(&mut self.seat),
            RowKind::Distance => Some(&mut self.distance),
            RowKind::Probe => Some(&mut self.probe),
        }
    }

    /// `KIND=MM` (e.g. `seat=0.005`) into `self`; a one-line error otherwise.
    pub fn set_from(&mut self, text: &str) -> Result<RowKind, String> {
        let keys: Vec<&str> = RowKind::ALL[1..].iter().map(|k| k.noise_key()).collect();
        let bad = || {
            format!(
                "'{text}': a kind's noise is KIND=MM with KIND one of {} (e.g. seat=0.005)",
                keys.join(", ")
            )
        };
        let (k, v) = text.split_once('=').ok_or_else(bad)?;
        let kind = RowKind::from_key(k.trim()).filter(|k| *k != RowKind::Tracker).ok_or_else(bad)?;
        let v: f64 = v.trim().parse().map_err(|_| bad())?;
        if !(v.is_finite() && v > 0.0) {
            return Err(format!("'{text}': the {} noise must be finite and > 0 (mm)", kind.name()));
        }
        *self.get_mut(kind).expect("an instrument kind") = Some(v);
        Ok(kind)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_parse_and_refuse_bad_values() {
        let mut k = KindNoise::default();
        assert_eq!(k.set_from("seat=0.005"), Ok(RowKind::Seat));
        assert_eq!(k.set_from(" distance = 0.002 "), Ok(RowKind::Distance));
        assert_eq!((k.seat, k.distance), (Some(0.005), Some(0.002)));
        assert!(k.set_from("seat=0").unwrap_err().contains("> 0"));
        assert!(k.set_from("seat=-1").is_err());
        assert_eq!(k.set_from("probe=0.005"), Ok(RowKind::Probe));
        assert_eq!(k.probe, Some(0.005));
        assert!(k.set_from("touch=0.1").unwrap_err().contains("KIND=MM"));
        assert!(k.set_from("position=0.1").is_err());
    }
}
