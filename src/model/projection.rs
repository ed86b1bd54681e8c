//! Projection of a model onto a smaller one: how far two mechanisms' tool poses lie apart over
//! configurations spread over the workspace ([`compare`], [`spread_configurations`]), and a
//! small Gauss–Newton least-squares fit ([`least_squares`]) for controllers whose parameter set
//! is smaller than the calibrated model's (`crate::io::controllers`).
use crate::error::KinError;
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use nalgebra::{DMatrix, DVector};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

/// How far two models' tool poses lie apart over a set of configurations.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PoseDifference {
    /// Number of configurations compared.
    pub poses: usize,
    /// Largest tool-position difference (mm).
    pub position_max_mm: f64,
    /// RMS of the tool-position differences (mm).
    pub position_rms_mm: f64,
    /// Largest tool-rotation difference (rad); `None` for a position-only task.
    pub rotation_max_rad: Option<f64>,
    /// RMS of the tool-rotation differences (rad); `None` for a position-only task.
    pub rotation_rms_rad: Option<f64>,
}

impl std::fmt::Display for PoseDifference {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "tool position max {:.3e} mm, RMS {:.3e} mm",
            self.position_max_mm, self.position_rms_mm
        )?;
        if let (Some(m), Some(r)) = (self.rotation_max_rad, self.rotation_rms_rad) {
            write!(f, "; rotation max {m:.3e} rad, RMS {r:.3e} rad")?;
        }
        write!(f, " ({} configurations)", self.poses)
    }
}

/// `n` configurations spread over `model`'s workspace (its own draw for closed loops, inputs
/// uniform within their limits otherwise), from `seed`.
pub fn spread_configurations(model: &dyn Mechanism, inputs: &[InputSpec], n: usize, seed: u64) -> Result<Vec<Vec<f64>>, KinError> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    crate::simulate::random_configurations(model, inputs, n, &mut rng)
}

/// The tool-pose differences between `a` and `b` at `configurations`; rotations compared only
/// when `with_rotation`.
pub fn compare(a: &dyn Mechanism, b: &dyn Mechanism, configurations: &[Vec<f64>], with_rotation: bool) -> Result<PoseDifference, KinError> {
    let pairs = configurations
        .iter()
        .map(|q| Ok((a.forward(q)?, b.forward(q)?)))
        .collect::<Result<Vec<_>, KinError>>()?;
    Ok(PoseDifference::of(&pairs, with_rotation))
}

impl PoseDifference {
    /// The differences of pairs of tool poses; rotations only when `with_rotation`.
    pub fn of(pairs: &[(Pose, Pose)], with_rotation: bool) -> PoseDifference {
        let (mut pmax, mut psum, mut rmax, mut rsum) = (0.0f64, 0.0, 0.0f64, 0.0);
        for (ta, tb) in pairs {
            let e = se3::pose_error(ta, tb);
            let (dp, dr) = (e.fixed_rows::<3>(0).norm(), e.fixed_rows::<3>(3).norm());
            pmax = pmax.max(dp);
            psum += dp * dp;
            rmax = rmax.max(dr);
            rsum += dr * dr;
        }
        let n = pairs.len().max(1) as f64;
        PoseDifference {
            poses: pairs.len(),
            position_max_mm: pmax,
            position_rms_mm: (psum / n).sqrt(),
            rotation_max_rad: with_rotation.then_some(rmax),
            rotation_rms_rad: with_rotation.then_some((rsum / n).sqrt()),
        }
    }
}

/// Gauss–Newton on `residual(x)` from `x0` with a central-difference Jacobian (steps `h`), the
/// step the minimum-norm least-squares one (SVD, singular values below 1e-12 of the largest
/// dropped), until the step is below `1e-13·(1 + |x|)` or `iterations` are done. Returns the
/// parameters and the residual there.
pub fn least_squares<F>(x0: DVector<f64>, h: f64, iterations: usize, residual: F) -> Result<(DVector<f64>, DVector<f64>), KinError>
where
    F: Fn(&DVector<f64>) -> Result<DVector<f64>, KinError>,
{
    let mut x = x0;
    let mut r = residual(&x)?;
    for _ in 0..iterations {
        let mut j = DMatrix::zeros(r.len(), x.len());
        for c in 0..x.len() {
            let (mut xp, mut xm) = (x.clone(), x.clone());
            xp[c] += h;
            xm[c] -= h;
            let d = (residual(&xp)? - residual(&xm)?) / (2.0 * h);
            j.set_column(c, &d);
        }
        let svd = j.svd(true, true);
        let tol = 1e-12 * svd.singular_values.max();
        let step = svd.solve(&(-&r), tol).map_err(|e| KinError::Singular {
            what: format!("projection least squares: {e}"),
            condition: f64::INFINITY,
        })?;
        let next = &x + &step;
        let rn = residual(&next)?;
        if rn.norm() > r.norm() * (1.0 + 1e-12) + 1e-300 {
            break;
        }
        let small = step.norm() <= 1e-13 * (1.0 + x.norm());
        x = next;
        r = rn;
        if small {
            break;
        }
    }
    Ok((x, r))
}

/// Which parameters of `model` (indices `which`) move its tool point in ways a controller's
/// parameters cannot: each parameter's column of tool-position changes over `configurations`
/// (central differences of [`Mechanism::retract`] by `h`), the part of it outside the span of
/// `controller` (the controller's own columns, rows in the same order: x, y, z per
/// configuration). Returns `(index, fraction outside, outside)` — the part outside relative to
/// the column, and its RMS per configuration (mm per unit of the parameter) — for the
/// parameters whose fraction exceeds `threshold` and whose part outside is above 1e-9 mm per
/// unit, largest part outside first.
pub fn unrepresented_positions(
    model: &dyn Mechanism,
    which: &[usize],
    configurations: &[Vec<f64>],
    controller: &DMatrix<f64>,
    h: f64,
    threshold: f64,
) -> Result<Vec<(usize, f64, f64)>, KinError> {
    let rows = 3 * configurations.len();
    let svd = controller.clone().svd(true, false);
    let u = svd.u.expect("asked for U");
    let smax = svd.singular_values.max();
    let basis: Vec<usize> = (0..svd.singular_values.len())
        .filter(|&k| svd.singular_values[k] > 1e-10 * smax)
        .collect();
    let n = model.n_params();
    let mut out = Vec::new();
    for &j in which {
        let mut col = DVector::zeros(rows);
        for sign in [1.0, -1.0] {
            let mut m = model.box_clone();
            let mut d = DVector::zeros(n);
            d[j] = sign * h;
            m.retract(&d);
            for (k, q) in configurations.iter().enumerate() {
                let p = m.forward(q)?.translation.vector;
                for c in 0..3 {
                    col[3 * k + c] += sign * p[c] / (2.0 * h);
                }
            }
        }
        let norm = col.norm();
        if norm == 0.0 {
            continue;
        }
        let mut inside = DVector::zeros(rows);
        for &b in &basis {
            let ub = u.column(b);
            inside += ub * ub.dot(&col);
        }
        let outside = (&col - inside).norm();
        let rms = outside / (configurations.len().max(1) as f64).sqrt();
        if outside / norm > threshold && rms > 1e-9 {
            out.push((j, outside / norm, rms));
        }
    }
    out.sort_by(|a, b| b.2.total_cmp(&a.2));
    Ok(out)
}
