//! How many rows of a data set refer to each artifact (seat, pivot, sphere, plane, datum cube):
//! what `kinecal data check` lists, e.g. `sphere 0: 40 touches, sphere 1: 40 touches`.
use super::{Measurement, Observation, PointKind, Touch};
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;

/// The rows of one artifact ([`artifact_rows`]).
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct ArtifactRows {
    /// The artifact's kind.
    pub kind: PointKind,
    /// Its number in the data (`seat`, `pivot`, `sphere`, `plane` column; the cube is 0).
    pub id: usize,
    /// Rows referring to it.
    pub rows: usize,
    /// A datum cube's touches per face (`0..5`: `+x, −x, +y, −y, +z, −z`); empty for the other
    /// kinds.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub faces: Vec<usize>,
}

impl ArtifactRows {
    /// The artifact's name in messages and summaries: `sphere 0`, `cube 0`, `seat 3`.
    pub fn name(&self) -> String {
        format!("{} {}", self.kind.name(), self.id)
    }
}

impl fmt::Display for ArtifactRows {
    /// `seat 3: 12 rows`, `pivot 1: 30 lengths`, `sphere 0: 40 touches`, `plane 0: 40 touches`,
    /// `cube 0: faces 0..5, 20 touches each` (or, unequal, `cube 0: 47 touches, faces 0..5: 8,
    /// 8, 7, 8, 8, 8`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (name, rows) = (self.name(), self.rows);
        match self.kind {
            PointKind::Seat => write!(f, "{name}: {rows} rows"),
            PointKind::Pivot => write!(f, "{name}: {rows} lengths"),
            PointKind::Sphere | PointKind::Plane => write!(f, "{name}: {rows} touches"),
            PointKind::Cube => match self.faces.first() {
                Some(&n) if n > 0 && self.faces.iter().all(|&m| m == n) && n * self.faces.len() == rows => {
                    write!(f, "{name}: faces 0..5, {n} touches each")
                }
                _ => {
                    let each: Vec<String> = self.faces.iter().map(usize::to_string).collect();
                    write!(f, "{name}: {rows} touches, faces 0..5: {}", each.join(", "))
                }
            },
        }
    }
}

/// The artifacts `measurements` refer to, by kind then number, each with its rows (a datum
/// cube's per face too); tracker rows refer to none and are not counted.
pub fn artifact_rows(measurements: &[Measurement]) -> Vec<ArtifactRows> {
    let mut out: BTreeMap<(PointKind, usize), ArtifactRows> = BTreeMap::new();
    for m in measurements {
        let Some((kind, id)) = m.obs.artifact_point() else { continue };
        let entry = out.entry((kind, id)).or_insert_with(|| ArtifactRows {
            kind,
            id,
            rows: 0,
            faces: if kind == PointKind::Cube { vec![0; 6] } else { Vec::new() },
        });
        entry.rows += 1;
        if let Observation::Touch(Touch::Face { face, .. }) = m.obs {
            if let Some(n) = entry.faces.get_mut(face) {
                *n += 1;
            }
        }
    }
    out.into_values().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(obs: Observation) -> Measurement {
        Measurement {
            q: vec![0.0],
            obs,
            joints: Vec::new(),
        }
    }

    #[test]
    fn rows_are_counted_per_artifact_and_cube_face() {
        let face = |face| {
            row(Observation::Touch(Touch::Face {
                face,
                edge: 200.0,
                probe: 1.5,
            }))
        };
        let mut rows: Vec<Measurement> = (0..6).flat_map(|j| [face(j), face(j)]).collect();
        rows.extend([row(Observation::Seat(3)), row(Observation::Seat(3))]);
        let counted = artifact_rows(&rows);
        let text: Vec<String> = counted.iter().map(ToString::to_string).collect();
        assert_eq!(text, ["seat 3: 2 rows", "cube 0: faces 0..5, 2 touches each"]);
        rows.push(face(4));
        let cube = artifact_rows(&rows).pop().unwrap().to_string();
        assert_eq!(cube, "cube 0: 13 touches, faces 0..5: 2, 2, 2, 2, 3, 2");
    }
}
