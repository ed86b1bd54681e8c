//! The limb-by-limb elimination of the closure's Newton systems: a limb's rows involve only the
//! platform twist and its own passive joints (and, for the identification Jacobian, its own
//! parameters), so eliminating each limb's passive joints on the stack leaves six platform
//! equations — the same solution as a dense solve of the whole closure, at a fraction of the cost.
use super::*;

impl LimbMechanism {
    /// The Newton step `F·dz = −r` of [`closure`](Self::closure) (passive columns) limb by limb,
    /// for a machine with as many equations as unknowns: a limb's rows involve only the platform
    /// twist `dζ` and its own passive joints, `A_i·dz_i + B_i·dζ = −r_i`. Gaussian elimination
    /// with partial pivoting on `A_i` (at most 6 × 6, on the stack) leaves `m_i − n_i` equations
    /// in `dζ` alone; the six of all limbs give `dζ`, back substitution the `dz_i`. The same
    /// solution as a dense solve of `F`, without factorising the whole of it. `None` where the
    /// system is not square, a limb has more passive joints than equations, or a pivot is (nearly)
    /// zero: the caller then solves `F` whole, which also names a singularity.
    pub(super) fn step_by_limbs(&self, f: &DMatrix<f64>, r: &DVector<f64>) -> Option<DVector<f64>> {
        if f.nrows() != f.ncols() || self.linked() {
            return None;
        }
        // Each limb's eliminated rows, [U | B' | r'] per pivot row.
        let mut pivots: Vec<([[f64; 13]; 6], usize, usize)> = Vec::with_capacity(self.limbs.len());
        let mut s = nalgebra::Matrix6::zeros();
        let mut t = nalgebra::Vector6::zeros();
        let mut reduced = 0;
        let (mut row, mut col) = (0, 6);
        for (i, l) in self.limbs.iter().enumerate() {
            let m = l.rows();
            let n = self.passive.iter().filter(|&&(li, _)| li == i).count();
            if n > m || m > 6 {
                return None;
            }
            // Row k: passive columns 0..n, platform columns 6..12, right-hand side 12.
            let mut b = [[0.0f64; 13]; 6];
            for (k, bk) in b.iter_mut().enumerate().take(m) {
                for j in 0..n {
                    bk[j] = f[(row + k, col + j)];
                }
                for j in 0..6 {
                    bk[6 + j] = f[(row + k, j)];
                }
                bk[12] = -r[row + k];
            }
            if !eliminate(&mut b[..m], n) {
                return None;
            }
            for bk in &b[n..m] {
                if reduced == 6 {
                    return None;
                }
                for j in 0..6 {
                    s[(reduced, j)] = bk[6 + j];
                }
                t[reduced] = bk[12];
                reduced += 1;
            }
            pivots.push((b, n, col));
            row += m;
            col += n;
        }
        let dzeta = platform_lu(s, reduced)?.solve(&t)?;
        let mut dz = DVector::zeros(f.ncols());
        dz.rows_mut(0, 6).copy_from(&dzeta);
        for (b, n, c) in pivots {
            for j in (0..n).rev() {
                let mut v = b[j][12] - (0..6).map(|k| b[j][6 + k] * dzeta[k]).sum::<f64>();
                for k in j + 1..n {
                    v -= b[j][k] * dz[c + k];
                }
                dz[c + j] = v / b[j][j];
            }
        }
        Some(dz)
    }

    /// The platform rows of `−F_z⁻¹·F_θ` (the identification Jacobian) by the elimination of
    /// [`step_by_limbs`](Self::step_by_limbs): limb `i`'s rows of `F_θ` are nonzero only in its
    /// own parameters' columns, so eliminating its passive joints leaves `S_i·dζ + T_i·dθ_i = 0`
    /// and `dζ = −S⁻¹·T·dθ`, a 6 × 6 solve. `None` where the step would be (then the caller
    /// solves `F_z` whole).
    pub(super) fn platform_jacobian_by_limbs(&self, fz: &DMatrix<f64>, fp: &DMatrix<f64>) -> Option<DMatrix<f64>> {
        if fz.nrows() != fz.ncols() || self.linked() {
            return None;
        }
        let mut s = nalgebra::Matrix6::zeros();
        let mut t = DMatrix::zeros(6, fp.ncols());
        let mut reduced = 0;
        let (mut row, mut col, mut pcol) = (0, 6, 0);
        for (i, l) in self.limbs.iter().enumerate() {
            let (m, p) = (l.rows(), l.n_params());
            let n = self.passive.iter().filter(|&&(li, _)| li == i).count();
            if n > m {
                return None;
            }
            // Row k: passive columns 0..n, platform columns n..n+6, the limb's parameters after.
            let mut b: Vec<Vec<f64>> = (0..m)
                .map(|k| {
                    let mut bk = Vec::with_capacity(n + 6 + p);
                    bk.extend((0..n).map(|j| fz[(row + k, col + j)]));
                    bk.extend((0..6).map(|j| fz[(row + k, j)]));
                    bk.extend((0..p).map(|j| fp[(row + k, pcol + j)]));
                    bk
                })
                .collect();
            if !eliminate(&mut b, n) {
                return None;
            }
            for bk in &b[n..m] {
                if reduced == 6 {
                    return None;
                }
                for j in 0..6 {
                    s[(reduced, j)] = bk[n + j];
                }
                for j in 0..p {
                    t[(reduced, pcol + j)] = bk[n + 6 + j];
                }
                reduced += 1;
            }
            row += m;
            col += n;
            pcol += p;
        }
        let mut out = -t;
        platform_lu(s, reduced)?.solve_mut(&mut out).then_some(out)
    }
}

/// The LU factors of the platform equations an elimination left, or `None` unless exactly six
/// were left and they are regular (pivots above 1e-9 of the largest).
fn platform_lu(s: nalgebra::Matrix6<f64>, reduced: usize) -> Option<nalgebra::linalg::LU<f64, nalgebra::U6, nalgebra::U6>> {
    if reduced != 6 {
        return None;
    }
    let lu = s.lu();
    let d = lu.u().diagonal().map(f64::abs);
    (d.min() > 1e-9 * d.max() && d.max().is_finite()).then_some(lu)
}

/// Gaussian elimination with partial pivoting of the first `n` columns of the rows `b` (a limb's
/// equations): afterwards rows `0..n` are upper triangular in those columns and rows `n..` are
/// zero there. `false` where a pivot is (nearly) zero or not finite.
fn eliminate<R: AsMut<[f64]>>(b: &mut [R], n: usize) -> bool {
    let m = b.len();
    let mut scale = 0.0f64;
    for bk in b.iter_mut() {
        scale = bk.as_mut()[..n].iter().fold(scale, |a, v| a.max(v.abs()));
    }
    for j in 0..n {
        let Some(p) = (j..m).max_by(|&a, &c| {
            let (x, y) = (b[a].as_mut()[j].abs(), b[c].as_mut()[j].abs());
            x.total_cmp(&y)
        }) else {
            return false;
        };
        // (NaN fails too.)
        if b[p].as_mut()[j].abs().partial_cmp(&(1e-9 * scale)) != Some(std::cmp::Ordering::Greater) {
            return false;
        }
        b.swap(j, p);
        let (top, below) = b.split_at_mut(j + 1);
        let pivot = top[j].as_mut();
        for bk in below.iter_mut() {
            let bk = bk.as_mut();
            let factor = bk[j] / pivot[j];
            if factor != 0.0 {
                for (x, y) in bk[j..].iter_mut().zip(&pivot[j..]) {
                    *x -= factor * y;
                }
            }
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::kinematics::lstsq;
    use super::*;
    use crate::model::limbs::limbs_from_text as limbs;

    /// Away from the solution (a perturbed platform and passive joints), the limb-by-limb step
    /// is the dense solve of the whole closure, for frame ends (Stewart) and point ends (6-RUS).
    #[test]
    fn the_limb_by_limb_step_is_the_dense_solve() {
        for text in [
            include_str!("../../../examples/models/stewart-limbs.toml"),
            include_str!("../../../examples/models/hexapod-6rus.toml"),
        ] {
            let m = limbs(text);
            for q in m.sample_configurations(5, 3).unwrap().unwrap() {
                let (x, passive) = m.forward_full(&q).unwrap();
                let x = se3::exp(&Twist::new(0.3, -0.2, 0.1, 0.01, 0.02, -0.01)) * x;
                let passive: Vec<f64> = passive.iter().enumerate().map(|(k, p)| p + 0.01 * (k as f64).sin()).collect();
                let (r, f) = m.closure(&x, &m.joints_of(&q, &passive), true);
                let blocked = m.step_by_limbs(&f, &r).expect("a square, regular closure");
                let dense = lstsq(&f, &(-r), "closure").unwrap();
                assert!((&blocked - &dense).amax() < 1e-10 * dense.amax(), "{m:?}", m = m.name);
            }
        }
    }

    /// The identification Jacobian's limb-by-limb elimination is the dense `−F_z⁻¹·F_θ`.
    #[test]
    fn the_limb_by_limb_jacobian_is_the_dense_one() {
        for text in [
            include_str!("../../../examples/models/stewart-limbs.toml"),
            include_str!("../../../examples/models/hexapod-6rus.toml"),
            include_str!("../../../examples/models/head-3prs.toml"),
        ] {
            let m = limbs(text);
            for q in m.sample_configurations(5, 4).unwrap().unwrap() {
                let (x, passive) = m.forward_full(&q).unwrap();
                let joints = m.joints_of(&q, &passive);
                let (_, fz) = m.closure(&x, &joints, true);
                let fp = m.closure_params(&x, &joints);
                let blocked = m.platform_jacobian_by_limbs(&fz, &fp).expect("a square, regular closure");
                let dense = -fz.lu().solve(&fp).unwrap().rows(0, 6).into_owned();
                assert!((&blocked - &dense).amax() < 1e-10 * dense.amax(), "{}", m.name);
            }
        }
    }
}
