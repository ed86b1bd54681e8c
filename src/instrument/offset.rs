//! The tool-point offset and the pivots fitted together on the lengths ([`super::start_points`]
//! without seats).
use super::{ArtifactPoint, PointKind};
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector, Vector3};

/// Levenberg–Marquardt on `L_i (+ e_k) − |p_i + R_i·t − c_k|` over the tool-point offset `t`,
/// the pivots' centres and the zeros `e_k` of pivots with readings (rows: pivot index, flange
/// pose, length); returns the offset, moves the centres and zeros, and returns the cost `Σ r²`
/// reached too. Stops where the cost no longer falls.
pub(super) fn fit_offset_and_pivots(rows: &[(usize, Pose, f64)], t0: Vector3<f64>, points: &mut [ArtifactPoint]) -> (Vector3<f64>, f64) {
    // The zeros' columns, after the centres'.
    let mut zcol = vec![None; points.len()];
    let mut n = 3 + 3 * points.len();
    for (k, p) in points.iter().enumerate() {
        if p.zero.is_some() {
            (zcol[k], n) = (Some(n), n + 1);
        }
    }
    let residual = |x: &DVector<f64>| -> DVector<f64> {
        let t = Vector3::new(x[0], x[1], x[2]);
        DVector::from_iterator(
            rows.len(),
            rows.iter().map(|(k, pose, l)| {
                let c = x.fixed_rows::<3>(3 + 3 * k).into_owned();
                l + zcol[*k].map_or(0.0, |z| x[z]) - (pose.translation.vector + pose.rotation * t - c).norm()
            }),
        )
    };
    let mut x = DVector::zeros(n);
    x.fixed_rows_mut::<3>(0).copy_from(&t0);
    for (k, p) in points.iter().enumerate() {
        x.fixed_rows_mut::<3>(3 + 3 * k).copy_from(&p.centre);
        if let (Some(c), Some(z)) = (zcol[k], p.zero) {
            x[c] = z.value - z.reference;
        }
    }
    let mut r = residual(&x);
    let mut lambda = 1e-3;
    for _ in 0..200 {
        let t = Vector3::new(x[0], x[1], x[2]);
        let mut j = DMatrix::zeros(rows.len(), n);
        for (i, (k, pose, _)) in rows.iter().enumerate() {
            let c = x.fixed_rows::<3>(3 + 3 * k).into_owned();
            let d = pose.translation.vector + pose.rotation * t - c;
            let u = d.try_normalize(1e-12).unwrap_or_else(Vector3::zeros);
            let dt = pose.rotation.to_rotation_matrix().matrix().transpose() * u;
            for a in 0..3 {
                j[(i, a)] = -dt[a];
                j[(i, 3 + 3 * k + a)] = u[a];
            }
            if let Some(z) = zcol[*k] {
                j[(i, z)] = 1.0;
            }
        }
        let jtj = j.transpose() * &j;
        let g = j.transpose() * &r;
        let cost = r.norm_squared();
        let improved = damped_step(&jtj, &g, &mut lambda, |step| {
            let trial = &x + step;
            let rt = residual(&trial);
            let lower = rt.norm_squared() < cost;
            if lower {
                (x, r) = (trial, rt);
            }
            lower
        });
        if !improved || cost - r.norm_squared() <= 1e-15 * (1.0 + cost) {
            break;
        }
    }
    for (k, p) in points.iter_mut().enumerate() {
        if p.kind == PointKind::Pivot {
            p.centre = x.fixed_rows::<3>(3 + 3 * k).into_owned();
        }
        if let (Some(c), Some(z)) = (zcol[k], p.zero.as_mut()) {
            z.value = z.reference + x[c];
        }
    }
    (Vector3::new(x[0], x[1], x[2]), r.norm_squared())
}

/// One Levenberg–Marquardt step on the normal equations `(jtj, g)`: the damping `lambda` raised
/// tenfold until `try_step` accepts the step (it evaluates it and keeps it where it lowers the
/// cost), then lowered threefold; whether a step was taken. Steps are minimum-norm: a direction
/// the residuals do not see (the offset and every pivot moved alike, on a machine that never
/// turns its tool) stays where it is instead of drifting with round-off.
pub(super) fn damped_step(jtj: &DMatrix<f64>, g: &DVector<f64>, lambda: &mut f64, mut try_step: impl FnMut(&DVector<f64>) -> bool) -> bool {
    for _ in 0..20 {
        let mut m = jtj.clone();
        for d in 0..jtj.nrows() {
            m[(d, d)] += *lambda * jtj[(d, d)].max(1e-12);
        }
        let svd = m.svd(true, true);
        let floor = 1e-10 * svd.singular_values.max();
        if let Ok(step) = svd.solve(&(-g), floor) {
            if try_step(&step) {
                *lambda = (*lambda / 3.0).max(1e-12);
                return true;
            }
        }
        *lambda *= 10.0;
    }
    false
}

/// The six points at `length` along each axis, either way (`+x, −x, +y, −y, +z, −z`): where the
/// tool-point offset fits are started besides the flange origin.
pub(super) fn along_each_axis(length: f64) -> [Vector3<f64>; 6] {
    std::array::from_fn(|k| {
        let mut v = Vector3::zeros();
        v[k / 2] = if k % 2 == 0 { length } else { -length };
        v
    })
}
