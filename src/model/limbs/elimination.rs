//! The limb-by-limb elimination of the closure's Newton systems: a limb's rows involve only the
//! platform twist and its own passive joints (and, for the identification Jacobian, its own
//! parameters), so eliminating each limb's passive joints on the stack leaves six platform
//! equations — the same solution as a dense solve of the whole closure, at a fraction of the cost.
use super::*;

impl LimbMechanism {
    /// The Newton step `F·dz = −r` of [`closure`](Self::closure) (passive columns) limb by limb,
    /// for a machine with as many equations as unknowns: a limb's rows involve only the platform
    /// twist `dζ` and its own passive joints, `A_i·dz_i + B_i·dζ = −r_i`. Gaussian elimination
    /// with partial pivoting on `A_i` (at most 12 × 6, on the stack) leaves `m_i − n_i` equations
    /// in `dζ` alone; the six of all limbs give `dζ`, back substitution the `dz_i`. The same
    /// solution as a dense solve of `F`, without factorising the whole of it. `None` where the
    /// system is not square, a limb has more passive joints than equations, or a pivot is (nearly)
    /// zero: the caller then solves `F` whole, which also names a singularity.
    ///
    /// With `all_joints` the unknowns are `[ζ | inputs | passive]` (inverse kinematics) and the
    /// rows after the closure's (the task equations) involve `dζ` alone: they join the platform
    /// equations the limbs leave.
    pub(super) fn step_by_limbs(&self, f: &DMatrix<f64>, r: &DVector<f64>, all_joints: bool) -> Option<DVector<f64>> {
        if f.nrows() != f.ncols() {
            return None;
        }
        let clusters = self.clusters.as_ref()?;
        let ni = self.inputs.len();
        // Each cluster's eliminated rows, [U | B' | r'] per pivot row, and its unknowns' columns.
        // (The pivot rows only: at most six, one per unknown.)
        let mut pivots: Vec<([[f64; 13]; 6], [usize; 6], usize)> = Vec::with_capacity(clusters.len());
        let mut s = nalgebra::Matrix6::zeros();
        let mut t = nalgebra::Vector6::zeros();
        let mut reduced = 0;
        let mut closure_rows = 0;
        for c in clusters {
            let mut cols = [0usize; 6];
            let mut n = 0;
            let inputs = if all_joints { &c.inputs[..] } else { &[] };
            let unknowns = inputs
                .iter()
                .map(|k| 6 + k)
                .chain(c.passive.iter().map(|k| if all_joints { 6 + ni + k } else { 6 + k }));
            for col in unknowns {
                *cols.get_mut(n)? = col;
                n += 1;
            }
            let m = c.rows.len();
            closure_rows += m;
            if n > m || m > MAX_ROWS {
                return None;
            }
            // Row k: unknown columns 0..n, platform columns 6..12, right-hand side 12.
            let mut b = [[0.0f64; 13]; MAX_ROWS];
            for (bk, &row) in b.iter_mut().zip(&c.rows) {
                for (j, &col) in cols[..n].iter().enumerate() {
                    bk[j] = f[(row, col)];
                }
                for j in 0..6 {
                    bk[6 + j] = f[(row, j)];
                }
                bk[12] = -r[row];
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
            let mut top = [[0.0f64; 13]; 6];
            top[..n].copy_from_slice(&b[..n]);
            pivots.push((top, cols, n));
        }
        for row in closure_rows..f.nrows() {
            if reduced == 6 {
                return None;
            }
            for j in 0..6 {
                s[(reduced, j)] = f[(row, j)];
            }
            t[reduced] = -r[row];
            reduced += 1;
        }
        let dzeta = platform_lu(s, reduced)?.solve(&t)?;
        let mut dz = DVector::zeros(f.ncols());
        dz.rows_mut(0, 6).copy_from(&dzeta);
        for (b, cols, n) in pivots {
            for j in (0..n).rev() {
                let mut v = b[j][12] - (0..6).map(|k| b[j][6 + k] * dzeta[k]).sum::<f64>();
                for k in j + 1..n {
                    v -= b[j][k] * dz[cols[k]];
                }
                dz[cols[j]] = v / b[j][j];
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
        if fz.nrows() != fz.ncols() {
            return None;
        }
        let clusters = self.clusters.as_ref()?;
        let mut s = nalgebra::Matrix6::zeros();
        let mut t = DMatrix::zeros(6, fp.ncols());
        let mut reduced = 0;
        for c in clusters {
            let (m, n, p) = (c.rows.len(), c.passive.len(), c.params.len());
            if n > m {
                return None;
            }
            // Row k: passive columns 0..n, platform columns n..n+6, the cluster's parameters after.
            let mut b: Vec<Vec<f64>> = c
                .rows
                .iter()
                .map(|&row| {
                    let mut bk = Vec::with_capacity(n + 6 + p);
                    bk.extend(c.passive.iter().map(|&k| fz[(row, 6 + k)]));
                    bk.extend((0..6).map(|j| fz[(row, j)]));
                    bk.extend(c.params.iter().map(|&col| fp[(row, col)]));
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
                for (j, &col) in c.params.iter().enumerate() {
                    t[(reduced, col)] = bk[n + 6 + j];
                }
                reduced += 1;
            }
        }
        let mut out = -t;
        platform_lu(s, reduced)?.solve_mut(&mut out).then_some(out)
    }
}

/// Most closure rows of a cluster the stack elimination takes (a limb closing on a frame, 6, with
/// an idle chain closing on one of its bodies with a point, 3; or two such).
const MAX_ROWS: usize = 12;

/// Limbs whose closure rows share passive joints: a limb that starts on the base with the limbs
/// that start or close on its bodies (its sub-closed loops). A cluster's rows involve only the
/// platform twist and its own passive joints (and, for the identification Jacobian, its own
/// parameters), so it is eliminated as a limb is.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Cluster {
    /// Its closure rows.
    rows: Vec<usize>,
    /// Its inputs (indices into the mechanism's inputs).
    inputs: Vec<usize>,
    /// Its passive joints (indices into the mechanism's passive joints).
    passive: Vec<usize>,
    /// Its error parameters' columns.
    params: Vec<usize>,
}

/// The clusters of `limbs` (`passive`: per passive unknown, its limb and joint); `None` where a
/// limb joins two limbs that start on the base (then the closure is solved whole).
pub(super) fn clusters(limbs: &[Limb], inputs: &[(usize, usize)], passive: &[(usize, usize)]) -> Option<Vec<Cluster>> {
    let root = |l: &Limb, i: usize| match (l.start, l.end_on) {
        (None, None) => Some(i),
        (Some(a), None) | (None, Some(a)) => Some(a.limb),
        (Some(a), Some(b)) => (a.limb == b.limb).then_some(a.limb),
    };
    let mut of_root = vec![None; limbs.len()];
    let mut out: Vec<Cluster> = Vec::new();
    let mut roots = Vec::with_capacity(limbs.len());
    let (mut row, mut param) = (0, 0);
    for (i, l) in limbs.iter().enumerate() {
        let r = root(l, i)?;
        let c = *of_root[r].get_or_insert_with(|| {
            out.push(Cluster {
                rows: Vec::new(),
                inputs: Vec::new(),
                passive: Vec::new(),
                params: Vec::new(),
            });
            out.len() - 1
        });
        roots.push(c);
        out[c].rows.extend(row..row + l.rows());
        out[c].params.extend(param..param + l.n_params());
        row += l.rows();
        param += l.n_params();
    }
    for (k, &(i, _)) in inputs.iter().enumerate() {
        out[roots[i]].inputs.push(k);
    }
    for (k, &(i, _)) in passive.iter().enumerate() {
        out[roots[i]].passive.push(k);
    }
    Some(out)
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
    /// is the dense solve of the whole closure, for frame ends (Stewart), point ends (6-RUS) and
    /// limbs with sub-closed loops (pm5: a cluster of a leg and its actuator limb).
    #[test]
    fn the_limb_by_limb_step_is_the_dense_solve() {
        for text in [
            include_str!("../../../examples/models/stewart-limbs.toml"),
            include_str!("../../../examples/models/hexapod-6rus.toml"),
            include_str!("../../../examples/models/pm5-limbs.toml"),
            include_str!("../../../examples/models/t3r1.toml"),
        ] {
            let m = limbs(text);
            for q in m.sample_configurations(5, 3).unwrap().unwrap() {
                let (x, passive) = m.forward_full(&q).unwrap();
                let x = se3::exp(&Twist::new(0.3, -0.2, 0.1, 0.01, 0.02, -0.01)) * x;
                let passive: Vec<f64> = passive.iter().enumerate().map(|(k, p)| p + 0.01 * (k as f64).sin()).collect();
                let (r, f) = m.closure(&x, &m.joints_of(&q, &passive), true);
                let blocked = m.step_by_limbs(&f, &r, false).expect("a square, regular closure");
                let dense = lstsq(&f, &(-r), "closure").unwrap();
                assert!((&blocked - &dense).amax() < 1e-10 * dense.amax(), "{m:?}", m = m.name);
            }
        }
    }

    /// The inverse kinematics' step (closure in every joint, plus the task equations) by limbs
    /// is the dense solve, for machines commanding less than a pose (3-PRS, pm5).
    #[test]
    fn the_limb_by_limb_inverse_step_is_the_dense_solve() {
        for text in [
            include_str!("../../../examples/models/head-3prs.toml"),
            include_str!("../../../examples/models/pm5-limbs.toml"),
        ] {
            let m = limbs(text);
            for q in m.sample_configurations(5, 5).unwrap().unwrap() {
                let (x, passive) = m.forward_full(&q).unwrap();
                let target = se3::exp(&Twist::new(0.5, -0.3, 0.2, 0.01, -0.02, 0.01)) * x;
                let x = se3::exp(&Twist::new(0.3, -0.2, 0.1, 0.01, 0.02, -0.01)) * x;
                let q: Vec<f64> = q.iter().enumerate().map(|(k, v)| v + 0.02 * (k as f64).cos()).collect();
                let (r, f) = m.closure(&x, &m.joints_of(&q, &passive), false);
                let (rt, ft) = super::super::kinematics::task_equations(m.task, &x, &target);
                let mut big = DMatrix::zeros(r.len() + rt.len(), f.ncols());
                big.view_mut((0, 0), f.shape()).copy_from(&f);
                big.view_mut((r.len(), 0), (rt.len(), 6)).copy_from(&ft);
                let rr = DVector::from_iterator(r.len() + rt.len(), r.iter().chain(rt.iter()).copied());
                let blocked = m.step_by_limbs(&big, &rr, true).expect("a square, regular system");
                let dense = lstsq(&big, &(-rr), "inverse").unwrap();
                assert!((&blocked - &dense).amax() < 1e-10 * dense.amax(), "{}", m.name);
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
            include_str!("../../../examples/models/pm5-limbs.toml"),
            include_str!("../../../examples/models/t3r1.toml"),
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
