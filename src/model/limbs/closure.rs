//! The closure equations of [`LimbMechanism`] and their derivatives with respect to the unknowns
//! (platform twist, joint values) and the error parameters (see the [parent module](super)).
//!
//! A limb starts on the base or on a body of another limb (the frame after one of its joints:
//! [`Limb::start`]) and closes on the platform or on such a body ([`Limb::end_on`]). A limb that
//! starts on a body `S` reaches `S·C(q)`, so its own columns are `Ad_S` times its chain's, and
//! the joints and parameters up to that body add their own spatial columns; a limb that closes on
//! a body `Y` sees `Y`'s columns with the opposite sign, as it sees the platform's.
use super::*;
use nalgebra::{Matrix3x6, Vector6};

/// How a limb's rows see a spatial twist: all six components (a frame end) or the velocity of a
/// point (a point end).
enum RowMap {
    Frame,
    Point(Matrix3x6<f64>),
}

impl RowMap {
    /// `f[row.., col] += sign·map·v`.
    fn add(&self, f: &mut DMatrix<f64>, row: usize, col: usize, v: &Vector6<f64>, sign: f64) {
        match self {
            RowMap::Frame => {
                for d in 0..6 {
                    f[(row + d, col)] += sign * v[d];
                }
            }
            RowMap::Point(m) => {
                let w = m * v;
                for d in 0..3 {
                    f[(row + d, col)] += sign * w[d];
                }
            }
        }
    }
}

/// A spatial joint Jacobian of a chain that starts at `s` instead of the base: `Ad_s·J`.
pub(super) fn moved(s: &Pose, j: &DMatrix<f64>) -> DMatrix<f64> {
    let a = se3::adjoint(s);
    DMatrix::from_fn(6, j.ncols(), |r, c| (0..6).map(|k| a[(r, k)] * j[(k, c)]).sum())
}

/// `[I | −[p]×]`: the velocity of point `p` under a spatial twist `(v, ω)`.
pub(super) fn point_map(p: &Vector3<f64>) -> nalgebra::Matrix3x6<f64> {
    let mut m = nalgebra::Matrix3x6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&Matrix3::identity());
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-se3::skew(p)));
    m
}

/// Column `j` of a 6-row matrix.
fn col6(m: &DMatrix<f64>, j: usize) -> Vector6<f64> {
    m.fixed_view::<6, 1>(0, j).into_owned()
}

/// Every limb's chain evaluated at its joint values (each in its own start frame), in one
/// allocation per quantity.
struct Evaluations {
    /// Each chain's end.
    ends: Vec<Pose>,
    /// The spatial joint Jacobians side by side (limb `i`'s columns from `offsets[i]`).
    jq: DMatrix<f64>,
    /// The frame after each joint, same columns.
    frames: Vec<Pose>,
    /// Each limb's first column.
    offsets: Vec<usize>,
}

impl Evaluations {
    /// Column `j` of limb `i`'s joint Jacobian.
    fn column(&self, i: usize, j: usize) -> Vector6<f64> {
        col6(&self.jq, self.offsets[i] + j)
    }
    /// The frame after joint `b.joint` of limb `b.limb`.
    fn body(&self, b: &BodyRef) -> Pose {
        self.frames[self.offsets[b.limb] + b.joint]
    }
}

/// What a limb's closure is built from at one configuration: its end in the world, the frame it
/// closes on, and the maps of its rows for its own end and for that frame.
struct LimbClosure {
    /// The pose it closes on (the platform or a body).
    target: Pose,
    /// The rows' view of a twist of the end.
    end_map: RowMap,
    /// The rows' view of a twist of the target.
    target_map: RowMap,
}

impl LimbMechanism {
    /// What the weakest motion the closure `fz` (`[ζ | passive]` columns) leaves free moves: ": it
    /// moves the platform and joint r1 of limb 'leg1'" (the unknowns with at least a tenth of the
    /// largest component of the null direction), or nothing where it cannot be told.
    pub(super) fn free_motion(&self, fz: &DMatrix<f64>) -> String {
        if fz.iter().any(|v| !v.is_finite()) {
            return String::new();
        }
        // (Through the normal matrix: square, so its SVD has the whole null space even where
        // there are fewer equations than unknowns. nalgebra's SVD does not return on non-finite
        // input: extreme placements overflow the product.)
        let n = fz.transpose() * fz;
        if n.iter().any(|v| !v.is_finite()) {
            return String::new();
        }
        let svd = n.svd(false, true);
        let Some(vt) = svd.v_t else { return String::new() };
        let Some(k) = (0..svd.singular_values.len()).min_by(|a, b| svd.singular_values[*a].total_cmp(&svd.singular_values[*b])) else {
            return String::new();
        };
        let v = vt.row(k);
        let big = v.amax();
        let mut parts = Vec::new();
        if (0..6).any(|c| v[c].abs() >= 0.1 * big) {
            parts.push("the platform".to_string());
        }
        for (c, &(i, j)) in self.passive.iter().enumerate() {
            if v[6 + c].abs() >= 0.1 * big {
                parts.push(format!(
                    "joint {} of limb '{}'",
                    self.limbs[i].chain.joints()[j].name,
                    self.limbs[i].name
                ));
            }
        }
        if parts.is_empty() {
            String::new()
        } else {
            format!(": it moves {}", parts.join(" and "))
        }
    }

    /// Whether some limb starts or ends on another limb's body (the limb-by-limb elimination
    /// then does not apply: a limb's rows involve another limb's joints).
    pub(super) fn linked(&self) -> bool {
        self.limbs.iter().any(|l| l.start.is_some() || l.end_on.is_some())
    }

    /// Each limb's chain at `joints`, evaluated once: its end, its spatial joint Jacobian and the
    /// frame after each joint.
    fn chain_evaluations(&self, joints: &Joints) -> Result<Evaluations, KinError> {
        let total: usize = self.limbs.iter().map(|l| l.chain.n_joints()).sum();
        let mut out = Evaluations {
            ends: Vec::with_capacity(self.limbs.len()),
            jq: DMatrix::zeros(6, total),
            frames: Vec::with_capacity(total),
            offsets: Vec::with_capacity(self.limbs.len()),
        };
        for (l, q) in self.limbs.iter().zip(joints) {
            let chain = &l.chain;
            if q.len() != chain.n_joints() || q.iter().any(|v| !v.is_finite()) {
                return Err(KinError::NonFinite("limb joint values".into()));
            }
            let off = out.frames.len();
            out.offsets.push(off);
            let mut g = Pose::identity();
            for (j, joint) in chain.joints().iter().enumerate() {
                let a = g * chain.initial_poses()[j];
                out.jq.set_column(off + j, &se3::adjoint_apply(&a, &joint.twist()));
                g = a * se3::exp_joint(&joint.twist(), q[j]);
                out.frames.push(g);
            }
            out.ends.push(g * chain.tool());
        }
        Ok(out)
    }

    /// Where limb `i` starts (the base: identity) at `joints`.
    pub(super) fn start_pose(&self, i: usize, joints: &Joints) -> Result<Pose, KinError> {
        match &self.limbs[i].start {
            None => Ok(Pose::identity()),
            Some(b) => Ok(self.limbs[b.limb].chain.frames(&joints[b.limb])?[b.joint]),
        }
    }

    /// What limb `i` closes on at `joints`: the platform at `x`, or a body.
    pub(super) fn target_pose(&self, i: usize, x: &Pose, joints: &Joints) -> Result<Pose, KinError> {
        match &self.limbs[i].end_on {
            None => Ok(*x),
            Some(b) => Ok(self.limbs[b.limb].chain.frames(&joints[b.limb])?[b.joint]),
        }
    }

    /// Limb `i`'s residual rows into `r` (from `row`) and what its derivatives need.
    fn limb_closure(&self, i: usize, end: Pose, target: Pose, r: &mut DVector<f64>, row: usize) -> LimbClosure {
        match &self.limbs[i].end {
            LimbEnd::Frame => {
                r.rows_mut(row, 6).copy_from(&se3::log(&(end * target.inverse())));
                LimbClosure {
                    target,
                    end_map: RowMap::Frame,
                    target_map: RowMap::Frame,
                }
            }
            LimbEnd::Point(a) => {
                let ta = (target * nalgebra::Point3::from(*a)).coords;
                let pe = end.translation.vector;
                r.rows_mut(row, 3).copy_from(&(pe - ta));
                LimbClosure {
                    target,
                    end_map: RowMap::Point(point_map(&pe)),
                    target_map: RowMap::Point(point_map(&ta)),
                }
            }
        }
    }

    /// Closure residual and its derivative with respect to `[ζ (6) | passive joints]` (with
    /// `all_joints`: `[ζ | every joint in input order, then passive order]`).
    pub(super) fn closure(&self, x: &Pose, joints: &Joints, passive_only: bool) -> (DVector<f64>, DMatrix<f64>) {
        // (Below −∞ nothing is: the derivative is always there.)
        let (r, f) = self.closure_unless_within(x, joints, passive_only, f64::NEG_INFINITY);
        let f = f.unwrap_or_else(|| DMatrix::zeros(0, 0));
        (r, f)
    }

    /// [`closure`](Self::closure), without the derivative where the residual's max-norm is below
    /// `tolerance` (a converged solve needs only the residual).
    pub(super) fn closure_unless_within(
        &self,
        x: &Pose,
        joints: &Joints,
        passive_only: bool,
        tolerance: f64,
    ) -> (DVector<f64>, Option<DMatrix<f64>>) {
        let rows: usize = self.limbs.iter().map(Limb::rows).sum();
        let cols = 6 + if passive_only {
            self.passive.len()
        } else {
            self.inputs.len() + self.passive.len()
        };
        let mut r = DVector::zeros(rows);
        // Non-finite joint values (a diverging solve): a non-finite residual, which every solver
        // takes as failure.
        let Ok(evals) = self.chain_evaluations(joints) else {
            r.fill(f64::NAN);
            return (r, Some(DMatrix::zeros(rows, cols)));
        };
        let mut limbs = Vec::with_capacity(self.limbs.len());
        let mut row = 0;
        for (i, l) in self.limbs.iter().enumerate() {
            limbs.push(self.limb_state(i, x, &evals, &mut r, row));
            row += l.rows();
        }
        if r.amax() < tolerance {
            return (r, None);
        }
        let mut f = DMatrix::zeros(rows, cols);
        let off = if passive_only { 6 } else { 6 + self.inputs.len() };
        // A joint's column and the factor its own column enters with (a parallelogram's distal
        // joint turns with −1 times its proximal one).
        let col_of = |i: usize, j: usize| {
            let (slot, factor) = match self.slots[i][j] {
                Slot::Follows(m) => (self.slots[i][m], -1.0),
                s => (s, 1.0),
            };
            match slot {
                Slot::Input(k) => (!passive_only).then_some((6 + k, factor)),
                Slot::Passive(k) => Some((off + k, factor)),
                Slot::Follows(_) => None,
            }
        };
        let mut row = 0;
        for (i, (l, (c, start))) in self.limbs.iter().zip(&limbs).enumerate() {
            for j in 0..l.chain.n_joints() {
                if let Some((col, factor)) = col_of(i, j) {
                    let v = evals.column(i, j);
                    let v = start.as_ref().map_or(v, |a| a * v);
                    c.end_map.add(&mut f, row, col, &v, factor);
                }
            }
            // The joints before the body it starts on move its end; those before the body it
            // closes on move the target (a body's spatial Jacobian is its limb's first columns).
            for (b, map, sign) in [(&l.start, &c.end_map, 1.0), (&l.end_on, &c.target_map, -1.0)] {
                let Some(b) = b else { continue };
                for j in 0..=b.joint {
                    if let Some((col, factor)) = col_of(b.limb, j) {
                        map.add(&mut f, row, col, &evals.column(b.limb, j), sign * factor);
                    }
                }
            }
            // Closing on the platform: its twist, with the opposite sign.
            if l.end_on.is_none() {
                match &c.target_map {
                    RowMap::Frame => {
                        for d in 0..6 {
                            f[(row + d, d)] = -1.0;
                        }
                    }
                    RowMap::Point(m) => f.view_mut((row, 0), (3, 6)).copy_from(&(-m)),
                }
            }
            row += l.rows();
        }
        (r, Some(f))
    }

    /// Limb `i`'s residual rows into `r` (from `row`), what its derivatives need, and the adjoint
    /// of where it starts (for a limb that starts on a body: its joint columns move with it).
    fn limb_state(
        &self,
        i: usize,
        x: &Pose,
        evals: &Evaluations,
        r: &mut DVector<f64>,
        row: usize,
    ) -> (LimbClosure, Option<nalgebra::Matrix6<f64>>) {
        let l = &self.limbs[i];
        let (e, start) = match &l.start {
            Some(b) => {
                let s = evals.body(b);
                (s * evals.ends[i], Some(se3::adjoint(&s)))
            }
            None => (evals.ends[i], None),
        };
        let target = match &l.end_on {
            Some(b) => evals.body(b),
            None => *x,
        };
        (self.limb_closure(i, e, target, r, row), start)
    }

    /// The closure's derivative with respect to the error parameters (rows × p) at a solved
    /// configuration.
    pub(super) fn closure_params(&self, x: &Pose, joints: &Joints) -> DMatrix<f64> {
        let rows: usize = self.limbs.iter().map(Limb::rows).sum();
        let p: usize = self.limbs.iter().map(Limb::n_params).sum();
        let mut f = DMatrix::zeros(rows, p);
        let mut offsets = Vec::with_capacity(self.limbs.len());
        let mut o = 0;
        for l in &self.limbs {
            offsets.push(o);
            o += l.n_params();
        }
        // Each limb's spatial parameter Jacobian (all dyads), in the world.
        let mut world = Vec::with_capacity(self.limbs.len());
        for (i, l) in self.limbs.iter().enumerate() {
            let Ok((e, jp)) = l.chain.forward_with_jacobian(&joints[i]) else {
                f.fill(f64::NAN);
                return f;
            };
            world.push((e, jp));
        }
        let mut row = 0;
        let mut scratch = DVector::zeros(rows);
        for (i, l) in self.limbs.iter().enumerate() {
            let (mut e, mut jp) = (world[i].0, world[i].1.clone());
            let (Ok(s), Ok(target)) = (self.start_pose(i, joints), self.target_pose(i, x, joints)) else {
                f.fill(f64::NAN);
                return f;
            };
            if l.start.is_some() {
                e = s * e;
                jp = se3::adjoint(&s) * jp;
            }
            let c = self.limb_closure(i, e, target, &mut scratch, row);
            // Its own dyads, then those of the bodies it starts on (its end moves with them) and
            // closes on (the target moves).
            let add = |f: &mut DMatrix<f64>, limb: usize, upto: usize, jac: &Matrix6xX<f64>, map: &RowMap, sign: f64| {
                for (col, (d, k)) in self.limbs[limb].param_slots().into_iter().enumerate() {
                    if d < upto {
                        let v = jac.fixed_view::<6, 1>(0, 6 * d + k).into_owned();
                        map.add(f, row, offsets[limb] + col, &v, sign);
                    }
                }
            };
            add(&mut f, i, usize::MAX, &jp, &c.end_map, 1.0);
            if let Some(b) = &l.start {
                add(&mut f, b.limb, b.joint + 1, &world[b.limb].1, &c.end_map, 1.0);
            }
            if let Some(b) = &l.end_on {
                add(&mut f, b.limb, b.joint + 1, &world[b.limb].1, &c.target_map, -1.0);
            }
            if matches!(l.end, LimbEnd::Point(_)) {
                let r = se3::rotation_matrix(&c.target);
                f.view_mut((row, offsets[i] + l.chain_params()), (3, 3)).copy_from(&(-r));
            }
            row += l.rows();
        }
        f
    }
}
