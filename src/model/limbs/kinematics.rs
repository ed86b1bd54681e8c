//! The kinematics of [`LimbMechanism`]: closure equations and their derivatives, forward and
//! inverse kinematics by Gauss–Newton with continuation (see the [parent module](super)).
use super::closure::{moved, point_map};
use super::*;

/// Most stages of a forward-kinematics continuation.
const MAX_STAGES: usize = 64;

impl LimbMechanism {
    /// `q` when every input is within its joint limits (1e-9 of slack), else the error naming
    /// the first that is not.
    pub(crate) fn within_limits(&self, q: Vec<f64>) -> Result<Vec<f64>, KinError> {
        for (k, &(i, j)) in self.inputs.iter().enumerate() {
            let joint = &self.limbs[i].chain.joints()[j];
            if let Some((lo, hi)) = joint.limits {
                if q[k] < lo - 1e-9 || q[k] > hi + 1e-9 {
                    let unit = if joint.kind == JointKind::Revolute { "rad" } else { "mm" };
                    return Err(KinError::OutOfWorkspace(format!(
                        "{} = {:.4} {unit} outside its limits [{lo:.4}, {hi:.4}]",
                        joint.name, q[k]
                    )));
                }
            }
        }
        Ok(q)
    }

    /// Joint values of every limb: the inputs placed, passive joints from `passive`.
    pub(super) fn joints_of(&self, q: &[f64], passive: &[f64]) -> Joints {
        let mut j: Joints = self.limbs.iter().map(|l| l.home.clone()).collect();
        for (k, &(i, jj)) in self.inputs.iter().enumerate() {
            j[i][jj] = q[k];
        }
        for (k, &(i, jj)) in self.passive.iter().enumerate() {
            j[i][jj] = passive[k];
        }
        self.couple(&mut j);
        j
    }

    /// Set each parallelogram's distal joint to minus its proximal one.
    pub(super) fn couple(&self, joints: &mut Joints) {
        for (slots, q) in self.slots.iter().zip(joints.iter_mut()) {
            couple_limb(slots, q);
        }
    }

    /// Gauss–Newton on the closure for the platform pose and passive joints at inputs `q`, from
    /// `(x, passive)`. Returns the solution or the residual reached.
    pub(super) fn solve_forward(
        &self,
        q: &[f64],
        mut x: Pose,
        mut passive: Vec<f64>,
        tolerance: f64,
    ) -> Result<(Pose, Vec<f64>), KinError> {
        let mut res = f64::INFINITY;
        let mut joints = self.joints_of(q, &passive);
        for _ in 0..MAX_ITERATIONS {
            for (&(i, j), p) in self.passive.iter().zip(&passive) {
                joints[i][j] = *p;
            }
            self.couple(&mut joints);
            let (r, f) = self.closure_unless_within(&x, &joints, true, tolerance);
            res = r.amax();
            if !res.is_finite() {
                break;
            }
            let Some(f) = f else {
                return Ok((x, passive));
            };
            self.forward_step(&f, &r, &mut x, &mut passive)?;
        }
        Err(KinError::NoConvergence {
            what: format!("forward kinematics of '{}' (closure)", self.name),
            iterations: MAX_ITERATIONS,
            residual: res,
        })
    }

    /// The Gauss–Newton step `F·dz = −r` applied to the platform pose and passive joints.
    fn forward_step(&self, f: &DMatrix<f64>, r: &DVector<f64>, x: &mut Pose, passive: &mut [f64]) -> Result<(), KinError> {
        let dz = match self.step_by_limbs(f, r, false) {
            Some(dz) => dz,
            None => lstsq(f, &(-r), "forward kinematics of a limb mechanism")?,
        };
        *x = se3::exp(&Twist::from_iterator(dz.rows(0, 6).iter().copied())) * *x;
        for (p, d) in passive.iter_mut().zip(dz.rows(6, dz.len() - 6).iter()) {
            *p += d;
        }
        Ok(())
    }

    /// The tangent of the forward kinematics at home, `dz/dq = −F_z⁻¹·F_q` (`[ζ | passive]` per
    /// input): the first continuation stage's predictor. `None` where `F_z` is not regular there.
    pub(super) fn home_tangent(&self) -> Option<DMatrix<f64>> {
        let joints: Joints = self.limbs.iter().map(|l| l.home.clone()).collect();
        let (_, f) = self.closure(&self.home, &joints, false);
        let ni = self.inputs.len();
        let np = self.passive.len();
        if f.nrows() != 6 + np {
            return None;
        }
        let fz = DMatrix::from_fn(6 + np, 6 + np, |r, c| if c < 6 { f[(r, c)] } else { f[(r, c + ni)] });
        let fq = f.columns(6, ni).into_owned();
        let t = fz.lu().solve(&(-fq))?;
        t.iter().all(|v| v.is_finite()).then_some(t)
    }

    pub(super) fn home_passive(&self) -> Vec<f64> {
        self.passive.iter().map(|&(i, j)| self.limbs[i].home[j]).collect()
    }

    /// Forward kinematics: the platform pose and the passive joint values at inputs `q`, followed
    /// from the home configuration along a straight path of the inputs (stages of at most
    /// [`FK_STAGE_RAD`] / [`FK_STAGE_MM`], more where a stage fails): Newton from home alone
    /// can land in another assembly mode.
    pub fn forward_full(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        check_inputs(q, self.inputs.len())?;
        let q0 = self.home_inputs();
        let reach = self
            .inputs
            .iter()
            .enumerate()
            .map(|(k, &(i, j))| {
                let stage = match self.limbs[i].chain.joints()[j].kind {
                    JointKind::Revolute => FK_STAGE_RAD,
                    JointKind::Prismatic => FK_STAGE_MM,
                };
                (q[k] - q0[k]).abs() / stage
            })
            .fold(0.0, f64::max);
        let mut stages = (reach.ceil().min(MAX_STAGES as f64) as usize).max(1);
        loop {
            let mut state = (self.home, self.home_passive());
            let mut before: Option<(Pose, Vec<f64>)> = None;
            let mut failed = None;
            for s in 1..=stages {
                let t = s as f64 / stages as f64;
                let qs: Vec<f64> = q0.iter().zip(q).map(|(a, b)| a + (b - a) * t).collect();
                // Seeded by linear extrapolation of the last two stages; intermediate stages
                // only need to stay on the branch, the last one is solved to round-off.
                let seed = match &before {
                    Some((x1, p1)) => {
                        let step = se3::log(&(state.0 * x1.inverse()));
                        let p: Vec<f64> = state.1.iter().zip(p1).map(|(a, b)| 2.0 * a - b).collect();
                        (se3::exp(&step) * state.0, p)
                    }
                    // The first stage: along the tangent at home, `dz = −F_z⁻¹·F_q·dq`.
                    None => match &self.tangent {
                        Some(tangent) => {
                            let dq = DVector::from_iterator(q.len(), qs.iter().zip(&q0).map(|(a, b)| a - b));
                            let dz = tangent * dq;
                            let x = se3::exp(&Twist::from_iterator(dz.rows(0, 6).iter().copied())) * state.0;
                            let p = state.1.iter().zip(dz.rows(6, dz.len() - 6).iter()).map(|(a, d)| a + d).collect();
                            (x, p)
                        }
                        None => state.clone(),
                    },
                };
                let tol = if s == stages { TOLERANCE } else { STAGE_TOLERANCE };
                match self.solve_forward(&qs, seed.0, seed.1, tol) {
                    Ok(st) => {
                        before = Some(std::mem::replace(&mut state, st));
                    }
                    Err(e) => {
                        failed = Some(e);
                        break;
                    }
                }
            }
            match failed {
                None => return Ok(state),
                Some(e) if stages >= MAX_STAGES => return Err(e),
                Some(_) => stages = (stages * 4).min(MAX_STAGES),
            }
        }
    }

    /// The inverse kinematics with every joint value of every limb (inputs first, then the
    /// passive joints) and the platform pose reached.
    pub fn inverse_full(&self, target: &Pose) -> Result<(Vec<f64>, Vec<f64>, Pose), KinError> {
        // A commanded pose fixes the platform, and each limb closes on the platform alone: the
        // limbs one by one (small systems), each followed from its home like the whole machine.
        if self.task == Task::Full && !self.linked() {
            let mut solved = Vec::with_capacity(self.limbs.len());
            for i in 0..self.limbs.len() {
                // A limb clearly out of reach is given up before Newton and its continuations.
                let reached = match self.limb_misses(i, target) {
                    Some(gap) => Err(gap),
                    None => self.limb_along_path(i, target),
                };
                solved.push(reached.map_err(|res| {
                    KinError::Unreachable(format!(
                        "inverse kinematics of '{}': limb '{}' does not reach the target (residual {res:.3e} mm / rad): the target is outside the workspace or across a singularity",
                        self.name, self.limbs[i].name
                    ))
                })?);
            }
            let pick = |list: &[(usize, usize)]| list.iter().map(|&(i, j)| solved[i][j]).collect::<Vec<f64>>();
            return Ok((pick(&self.inputs), pick(&self.passive), *target));
        }
        let start = (self.home, self.home_inputs(), self.home_passive());
        let mut last = Err(KinError::Unreachable("no attempt".into()));
        for steps in [1usize, 4, 16] {
            let mut state = start.clone();
            let mut ok = true;
            for s in 1..=steps {
                let t = s as f64 / steps as f64;
                let goal = interpolate(&self.home, target, t);
                match self.solve_inverse(&goal, state.clone()) {
                    Ok(st) => state = st,
                    Err(e) => {
                        last = Err(e);
                        ok = false;
                        break;
                    }
                }
            }
            if ok {
                return Ok((state.1, state.2, state.0));
            }
        }
        last
    }

    pub(super) fn solve_inverse(
        &self,
        target: &Pose,
        (mut x, mut q, mut passive): (Pose, Vec<f64>, Vec<f64>),
    ) -> Result<(Pose, Vec<f64>, Vec<f64>), KinError> {
        let mut res = f64::INFINITY;
        for _ in 0..MAX_ITERATIONS {
            let joints = self.joints_of(&q, &passive);
            let (r, f) = self.closure(&x, &joints, false);
            let (rt, ft) = task_equations(self.task, &x, target);
            let n = f.ncols();
            let mut big = DMatrix::zeros(r.len() + rt.len(), n);
            big.view_mut((0, 0), f.shape()).copy_from(&f);
            big.view_mut((r.len(), 0), (rt.len(), 6)).copy_from(&ft);
            let mut rr = DVector::zeros(r.len() + rt.len());
            rr.rows_mut(0, r.len()).copy_from(&r);
            rr.rows_mut(r.len(), rt.len()).copy_from(&rt);
            res = rr.amax();
            if !res.is_finite() {
                break;
            }
            if res < TOLERANCE {
                return Ok((x, q, passive));
            }
            let dz = match self.step_by_limbs(&big, &rr, true) {
                Some(dz) => dz,
                None => lstsq(&big, &(-rr), "inverse kinematics of a limb mechanism")?,
            };
            x = se3::exp(&Twist::from_iterator(dz.rows(0, 6).iter().copied())) * x;
            for (v, d) in q.iter_mut().zip(dz.rows(6, self.inputs.len()).iter()) {
                *v += d;
            }
            for (v, d) in passive.iter_mut().zip(dz.rows(6 + self.inputs.len(), self.passive.len()).iter()) {
                *v += d;
            }
        }
        Err(KinError::Unreachable(format!(
            "inverse kinematics of '{}' did not close (residual {res:.3e} mm / rad): the target is outside the workspace or across a singularity",
            self.name
        )))
    }

    /// Limb `i`'s joints with its end on the platform at `target`: Newton from its home values,
    /// else along the straight path of platform poses from home in 4, then 16 stages (the
    /// continuation of the whole machine, for one limb). The residual reached where it fails.
    fn limb_along_path(&self, i: usize, target: &Pose) -> Result<Vec<f64>, f64> {
        let home = &self.limbs[i].home;
        let base = Pose::identity();
        let (q, mut worst) = self.solve_limb_from(i, &base, target, home.clone());
        if worst < TOLERANCE {
            return Ok(q);
        }
        'stages: for steps in [4usize, 16] {
            let mut q = home.clone();
            for s in 1..=steps {
                let goal = interpolate(&self.home, target, s as f64 / steps as f64);
                let (next, res) = self.solve_limb_from(i, &base, &goal, q);
                // (NaN fails too.)
                if res.partial_cmp(&TOLERANCE) != Some(std::cmp::Ordering::Less) {
                    worst = res;
                    continue 'stages;
                }
                q = next;
            }
            return Ok(q);
        }
        Err(worst)
    }

    /// Limb `i`'s joints that put its end as close as it gets to the platform at `x` (least
    /// squares from its home values), and the largest remaining residual (mm / rad). For a limb
    /// that starts on the base.
    #[cfg(test)]
    pub(super) fn solve_limb_at(&self, i: usize, x: &Pose) -> (Vec<f64>, f64) {
        self.solve_limb_from(i, &Pose::identity(), x, self.limbs[i].home.clone())
    }

    /// Limb `i`'s joints, from `q`, that put its end, with its chain starting at `start`, as close
    /// as it gets to `x` (the platform or the body it closes on; least squares), and the largest
    /// remaining residual (mm / rad).
    pub(super) fn solve_limb_from(&self, i: usize, start: &Pose, x: &Pose, mut q: Vec<f64>) -> (Vec<f64>, f64) {
        let l = &self.limbs[i];
        let shifted = *start != Pose::identity();
        // A parallelogram's distal joint follows its proximal one: one column for both.
        let slots = &self.slots[i];
        let free: Vec<usize> = (0..q.len()).filter(|j| !matches!(slots[*j], Slot::Follows(_))).collect();
        // Each free joint's column in the reduced Jacobian.
        let mut reduced_col = vec![0; q.len()];
        for (c, &j) in free.iter().enumerate() {
            reduced_col[j] = c;
        }
        let mut res = f64::INFINITY;
        let mut stalled = false;
        // The closest the iteration came: on a target the limb cannot reach (an inconsistent
        // drawing) Gauss–Newton can wander off its least-squares minimum.
        let mut closest: Option<(Vec<f64>, f64)> = None;
        for _ in 0..MAX_ITERATIONS {
            couple_limb(slots, &mut q);
            let Ok((mut e, mut jq)) = l.chain.joint_jacobian(&q) else {
                return (q, f64::INFINITY);
            };
            if shifted {
                e = start * e;
                jq = moved(start, &jq);
            }
            if free.len() < q.len() {
                let mut reduced = DMatrix::zeros(6, free.len());
                for (c, &j) in free.iter().enumerate() {
                    reduced.set_column(c, &jq.column(j));
                }
                for (k, s) in slots.iter().enumerate() {
                    if let Slot::Follows(m) = s {
                        let c = reduced_col[*m];
                        let col = reduced.column(c) - jq.column(k);
                        reduced.set_column(c, &col);
                    }
                }
                jq = reduced;
            }
            let (r, f) = match &l.end {
                LimbEnd::Frame => (DVector::from_column_slice(se3::log(&(e * x.inverse())).as_slice()), jq.clone()),
                LimbEnd::Point(a) => {
                    let xa = x * nalgebra::Point3::from(*a);
                    let pe = e.translation.vector;
                    let m = point_map(&pe);
                    let fm = DMatrix::from_fn(3, jq.ncols(), |rr, c| (0..6).map(|k| m[(rr, k)] * jq[(k, c)]).sum());
                    (DVector::from_column_slice((pe - xa.coords).as_slice()), fm)
                }
            };
            res = r.amax();
            if !res.is_finite() {
                return (q, f64::INFINITY);
            }
            if closest.as_ref().is_none_or(|c| res < c.1) {
                closest = Some((q.clone(), res));
            }
            // (A step at the round-off of the joint values was the last one that could help: its
            // residual, just evaluated, is the answer.)
            if res < TOLERANCE || stalled {
                break;
            }
            // Square: LU; else minimum-norm steps (a limb with more joints than equations, or at a
            // singularity, moves as little as it can).
            let r = -r;
            let square = if f.is_square() { lstsq(&f, &r, "limb").ok() } else { None };
            let d = match square {
                Some(d) => d,
                None if f.iter().any(|v| !v.is_finite()) => return (q, f64::INFINITY),
                None => {
                    let svd = f.svd(true, true);
                    let tol = svd.singular_values.max() * 1e-10;
                    let Ok(d) = svd.solve(&r, tol) else { return (q, res) };
                    d
                }
            };
            for (&j, dv) in free.iter().zip(d.iter()) {
                q[j] += dv;
            }
            stalled = d.amax() < 1e-13;
        }
        couple_limb(slots, &mut q);
        // Where it ended far from the closest it came, that is the answer (a converged or
        // settled solve ends there itself, unchanged).
        match closest {
            Some((best, r)) if res > 2.0 * r => (best, r),
            _ => (q, res),
        }
    }
}

/// Set each parallelogram's distal joint of a limb (`slots`: its joints' [`Slot`]s) to minus its
/// proximal one.
impl LimbMechanism {
    /// [`Mechanism::sample_configurations`]: poses drawn in the workspace box, solved by the
    /// inverse kinematics (`None` without a workspace).
    pub(super) fn sample_in_workspace(&self, n: usize, seed: u64) -> Option<Result<Vec<Vec<f64>>, KinError>> {
        use rand::{RngExt, SeedableRng};
        let ws = self.workspace.as_ref()?;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let mut out = Vec::with_capacity(n);
        let mut tries = 0;
        while out.len() < n {
            tries += 1;
            if tries > 50 * n.max(1) {
                return Some(Err(KinError::Unreachable(format!(
                    "'{}': only {} of {n} configurations drawn in its workspace could be reached (check [mechanism.workspace] against the limbs and joint limits)",
                    self.name,
                    out.len()
                ))));
            }
            let mut draw = |lo: f64, hi: f64| if hi > lo { rng.random_range(lo..hi) } else { lo };
            let p = Vector3::new(
                draw(ws.position_min.x, ws.position_max.x),
                draw(ws.position_min.y, ws.position_max.y),
                draw(ws.position_min.z, ws.position_max.z),
            );
            let a: Vec<f64> = (0..3).map(|k| draw(ws.rpy_min[k], ws.rpy_max[k])).collect();
            let rot = nalgebra::UnitQuaternion::from_euler_angles(a[0], a[1], a[2]) * self.home.rotation;
            let target = Pose::from_parts(nalgebra::Translation3::from(p), rot);
            if let Ok(q) = self.inverse(&target, None) {
                out.push(q);
            }
        }
        Some(Ok(out))
    }
}

fn couple_limb(slots: &[Slot], q: &mut [f64]) {
    for (j, s) in slots.iter().enumerate() {
        if let Slot::Follows(m) = s {
            q[j] = -q[*m];
        }
    }
}

/// The commanded part of `x` against `target` and its derivative with respect to `ζ`.
pub(super) fn task_equations(task: Task, x: &Pose, target: &Pose) -> (DVector<f64>, DMatrix<f64>) {
    match task {
        Task::Full => {
            let e = se3::log(&(x * target.inverse()));
            (DVector::from_column_slice(e.as_slice()), DMatrix::identity(6, 6))
        }
        Task::Position => {
            let p = x.translation.vector;
            let m = point_map(&p);
            (
                DVector::from_column_slice((p - target.translation.vector).as_slice()),
                DMatrix::from_fn(3, 6, |r, c| m[(r, c)]),
            )
        }
        Task::PositionAndYaw => {
            // Position, and the yaw atan2(R₁₀, R₀₀) of the x-axis r: d(yaw) = (r₀·dr₁ − r₁·dr₀)/(r₀² + r₁²)
            // with dr = ω × r.
            let p = x.translation.vector;
            let r = x.rotation * Vector3::x();
            let mut res = DVector::zeros(4);
            res.rows_mut(0, 3).copy_from(&(p - target.translation.vector));
            res[3] = se3::yaw_difference(target, x);
            let mut f = DMatrix::zeros(4, 6);
            f.view_mut((0, 0), (3, 6)).copy_from(&point_map(&p));
            let h = r.x * r.x + r.y * r.y;
            f[(3, 3)] = -r.x * r.z / h;
            f[(3, 4)] = -r.y * r.z / h;
            f[(3, 5)] = 1.0;
            (res, f)
        }
        Task::HeightAndAxis => {
            let (r, f) = task_equations(Task::PositionAndAxis, x, target);
            let keep = [2usize, 3, 4];
            (
                DVector::from_fn(3, |i, _| r[keep[i]]),
                DMatrix::from_fn(3, 6, |i, c| f[(keep[i], c)]),
            )
        }
        Task::PositionAndAxis => {
            // Position, and the tool z-axis: its x and y components in the target frame.
            let p = x.translation.vector;
            let z = x.rotation * Vector3::z();
            let rt = target.rotation.to_rotation_matrix().into_inner();
            let zl = rt.transpose() * z;
            let mut r = DVector::zeros(5);
            r.rows_mut(0, 3).copy_from(&(p - target.translation.vector));
            r[3] = zl.x;
            r[4] = zl.y;
            let mut f = DMatrix::zeros(5, 6);
            let m = point_map(&p);
            f.view_mut((0, 0), (3, 6)).copy_from(&m);
            // dz = ω × z: d(zl) = Rtᵀ·(−[z]×)·ω.
            let dz = rt.transpose() * (-se3::skew(&z));
            for c in 0..3 {
                f[(3, 3 + c)] = dz[(0, c)];
                f[(4, 3 + c)] = dz[(1, c)];
            }
            (r, f)
        }
    }
}

/// The pose a fraction `t` of the way from `a` to `b` (geodesic).
pub(super) fn interpolate(a: &Pose, b: &Pose, t: f64) -> Pose {
    if t >= 1.0 {
        return *b;
    }
    let p = a.translation.vector + (b.translation.vector - a.translation.vector) * t;
    let rot = a.rotation.slerp(&b.rotation, t);
    Pose::from_parts(nalgebra::Translation3::from(p), rot)
}

/// Minimum-norm least-squares solution of `f·x = b`; singular when `f` loses column rank.
pub(super) fn lstsq(f: &DMatrix<f64>, b: &DVector<f64>, what: &str) -> Result<DVector<f64>, KinError> {
    // nalgebra's SVD does not return on non-finite input.
    if f.iter().chain(b.iter()).any(|v| !v.is_finite()) {
        return Err(KinError::Singular {
            what: format!("{what} (non-finite values)"),
            condition: f64::INFINITY,
        });
    }
    // A square system (the usual case): LU, unless its pivots say it is nearly singular; then
    // the SVD decides and gives the condition number.
    if f.is_square() {
        let lu = f.clone().lu();
        let u = lu.u();
        let d = u.diagonal().map(f64::abs);
        if d.min() > d.max() * 1e-9 && d.max().is_finite() {
            if let Some(x) = lu.solve(b) {
                return Ok(x);
            }
        }
    }
    let svd = f.clone().svd(true, true);
    let hi = svd.singular_values.max();
    let lo = svd.singular_values.min();
    if !(hi.is_finite()) || f.ncols() > f.nrows() || lo <= hi / MAX_CONDITION {
        return Err(KinError::Singular {
            what: what.into(),
            condition: if lo > 0.0 { hi / lo } else { f64::INFINITY },
        });
    }
    svd.solve(b, 0.0).map_err(|_| KinError::Singular {
        what: what.into(),
        condition: f64::INFINITY,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::limbs::limbs_from_text as limbs;

    /// Each limb alone reaches a pose the machine reaches to the closure tolerance: the residual
    /// reported is the one after the last step (a stale one, 1.6e-11 mm, sent the 6-RUS inverse
    /// kinematics down the slow path of the whole machine).
    #[test]
    fn each_limb_alone_reaches_a_reachable_pose() {
        let m = limbs(include_str!("../../../examples/models/hexapod-6rus.toml"));
        for q in m.sample_configurations(20, 7).unwrap().unwrap() {
            let x = m.forward_full(&q).unwrap().0;
            for i in 0..m.limbs.len() {
                let (_, res) = m.solve_limb_at(i, &x);
                assert!(res < TOLERANCE, "limb {i}: {res:.3e}");
            }
        }
    }

    /// The task equations (all but the full pose's, whose identity is exact only at the target)
    /// have the derivative of central finite differences in the platform twist (`x ← exp(ζ)·x`),
    /// away from the target.
    #[test]
    fn task_equations_derivatives_are_the_finite_differences() {
        let x = se3::exp(&Twist::new(12.0, -30.0, 250.0, 0.2, -0.15, 0.7));
        let target = se3::exp(&Twist::new(10.0, -25.0, 240.0, 0.1, -0.1, 0.9));
        for task in [Task::Position, Task::PositionAndAxis, Task::HeightAndAxis, Task::PositionAndYaw] {
            let (_, f) = task_equations(task, &x, &target);
            let h = 1e-6;
            for c in 0..6 {
                let mut d = Twist::zeros();
                d[c] = h;
                let (rp, _) = task_equations(task, &(se3::exp(&d) * x), &target);
                let (rm, _) = task_equations(task, &(se3::exp(&(-d)) * x), &target);
                let fd = (rp - rm) / (2.0 * h);
                let err = (&fd - f.column(c)).amax();
                assert!(err < 1e-6 * (1.0 + fd.amax()), "{task:?} column {c}: {err:e}");
            }
        }
    }

    /// A non-finite system is an error, not an endless SVD.
    #[test]
    fn lstsq_refuses_non_finite_values() {
        let mut f = DMatrix::from_element(6, 5, 1.0);
        f[(2, 3)] = f64::NAN;
        assert!(lstsq(&f, &DVector::zeros(6), "test").is_err());
        assert!(lstsq(&DMatrix::identity(3, 3), &DVector::from_element(3, f64::INFINITY), "test").is_err());
    }
}
