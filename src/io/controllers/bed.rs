//! A printer's bed: the plane its probe touched, found with a calibrated model
//! ([`bed_from_touches`]), and Klipper's frame on it ([`Bed::frame`]).
//!
//! A printer calibrated from touches on its bed (and a few ballbar lengths) is known only up to
//! a rigid motion: nothing measured says where its base stands. The bed says where Klipper's
//! frame is: `z = 0` on the bed, `z` along its normal (toward the machine). The bed is the
//! least-squares plane through the calibrated model's tool points (the probe's centre) at the
//! bed's touches, moved by the probe's radius onto the surface: noise-free, the plane the
//! calibration fitted; with noise, the plane the calibrated model puts the touches on.
use super::ControllerError;
use crate::io::model_file::ModelFile;
use crate::measure::{Measurement, Observation, Touch};
use crate::model::projection::spread_configurations;
use crate::se3::Pose;
use nalgebra::{Matrix3, Rotation3, Translation3, UnitQuaternion, Vector3};
use std::collections::BTreeMap;

/// A plane in a model's frame (the frame its tool points are in: with `[frames]`, the
/// measurement frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bed {
    /// A point on the surface (the touches' centroid, moved onto the surface), mm.
    pub point: Vector3<f64>,
    /// Unit normal, toward the machine's workspace.
    pub normal: Vector3<f64>,
}

impl Bed {
    /// A frame on the bed: origin at [`Bed::point`], `z` along the normal, `x` the model's `x`
    /// axis projected onto the bed (its `y` where `x` stands nearly along the normal).
    pub fn frame(&self) -> Pose {
        let z = self.normal;
        let along = |a: Vector3<f64>| a - z * z.dot(&a);
        let x = if along(Vector3::x()).norm() > 0.1 {
            along(Vector3::x()).normalize()
        } else {
            along(Vector3::y()).normalize()
        };
        let y = z.cross(&x);
        let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[x, y, z]));
        Pose::from_parts(Translation3::from(self.point), UnitQuaternion::from_rotation_matrix(&r))
    }
}

/// The bed found from touches, and how flat the touches lie.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BedFit {
    /// The bed.
    pub bed: Bed,
    /// The plane's number in the data.
    pub plane: usize,
    /// Touches used.
    pub touches: usize,
    /// RMS distance of the probe's centres from their plane (mm).
    pub rms_mm: f64,
    /// Largest distance (mm).
    pub max_mm: f64,
}

/// The bed of `file` (a calibrated model) from the touches on plane `plane` among
/// `measurements` (rows of other kinds are skipped; `None`: the data's only plane). One-line
/// errors: no plane touches, several planes and none chosen, a plane not touched, fewer than
/// three touches or touches on a line, the model not reaching a touch's configuration.
pub fn bed_from_touches(file: &ModelFile, measurements: &[Measurement], plane: Option<usize>) -> Result<BedFit, ControllerError> {
    let bad = |m: String| ControllerError::Unsupported(m);
    let mut planes: BTreeMap<usize, Vec<(&Measurement, f64)>> = BTreeMap::new();
    for m in measurements {
        if let Observation::Touch(Touch::Plane { plane, probe }) = m.obs {
            planes.entry(plane).or_default().push((m, probe));
        }
    }
    let ids = || planes.keys().map(|k| k.to_string()).collect::<Vec<_>>().join(", ");
    let plane = match plane {
        Some(p) if planes.contains_key(&p) => p,
        Some(p) if planes.is_empty() => {
            return Err(bad(format!(
                "no plane touches (columns plane, probe_radius_mm) to find bed plane {p} from"
            )));
        }
        Some(p) => return Err(bad(format!("plane {p} is not touched in the data (planes touched: {})", ids()))),
        None => match planes.len() {
            0 => {
                return Err(bad(
                    "no plane touches (columns plane, probe_radius_mm): the bed is found from the probe's touches on it".into(),
                ))
            }
            1 => *planes.keys().next().expect("one plane"),
            _ => return Err(bad(format!("touches on planes {}: say which is the bed (--bed-plane K)", ids()))),
        },
    };
    let rows = &planes[&plane];
    if rows.len() < 3 {
        return Err(bad(format!(
            "plane {plane}: {} touches; at least 3 not on a line place the bed",
            rows.len()
        )));
    }
    let model = file.build();
    let points = rows
        .iter()
        .map(|(m, _)| {
            model
                .forward(&m.q)
                .map(|t| t.translation.vector)
                .map_err(|e| bad(format!("plane {plane}: the model does not reach a touch's configuration: {e}")))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let n = points.len() as f64;
    let centroid = points.iter().sum::<Vector3<f64>>() / n;
    let scatter = points
        .iter()
        .fold(Matrix3::zeros(), |s, p| s + (p - centroid) * (p - centroid).transpose());
    let eig = scatter.symmetric_eigen();
    let mut order = [0usize, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    let spread = eig.eigenvalues[order[1]].max(0.0).sqrt() / n.sqrt();
    if spread < 1e-3 {
        return Err(bad(format!(
            "plane {plane}: its touches lie on a line; touch the bed at three places at least, spread over it"
        )));
    }
    let mut normal: Vector3<f64> = eig.eigenvectors.column(order[0]).into_owned().normalize();
    // Toward the machine: the side of its workspace.
    let inputs = file.inputs();
    let inside = spread_configurations(&*model, &inputs, 50, super::PROJECTION_SEED + 3)?
        .iter()
        .filter_map(|q| model.forward(q).ok().map(|t| t.translation.vector))
        .map(|p| (p - centroid).dot(&normal))
        .sum::<f64>();
    if inside < 0.0 {
        normal = -normal;
    }
    let distances: Vec<f64> = points.iter().map(|p| (p - centroid).dot(&normal)).collect();
    let rms_mm = (distances.iter().map(|d| d * d).sum::<f64>() / n).sqrt();
    let max_mm = distances.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    let probe = rows.iter().map(|(_, r)| r).sum::<f64>() / n;
    Ok(BedFit {
        bed: Bed {
            point: centroid - probe * normal,
            normal,
        },
        plane,
        touches: rows.len(),
        rms_mm,
        max_mm,
    })
}
