//! [`ClosedLoop`] as a [`Mechanism`]: forward kinematics with the identification Jacobian,
//! inverse kinematics, retraction of the geometry, sampling of configurations.
use super::*;
use num_dual::DualSVec64;

impl<C: ConstraintSystem> Mechanism for ClosedLoop<C> {
    fn name(&self) -> &str {
        self.system.name()
    }
    /// The inverse starts from the per-limb closed form, never from a seed.
    fn inverse_ignores_seed(&self) -> bool {
        true
    }
    fn input_names(&self) -> Vec<String> {
        self.system.input_names()
    }
    fn params(&self) -> Vec<Param> {
        let mut p = self.system.geometry_params();
        if self.frame_errors {
            for n in TOOL_PARAMS {
                p.push(Param::new(n, Unit::Length, "tool"));
            }
            for (i, n) in BASE_PARAMS.iter().enumerate() {
                p.push(Param::new(*n, if i < 3 { Unit::Length } else { Unit::Angle }, "base"));
            }
        }
        p
    }
    fn n_params(&self) -> usize {
        self.n_params_total()
    }
    /// The system's drawing at its home pose (the inputs of its inverse kinematics there, the
    /// platform solved from them), in the world frame, with the tool offset from the platform.
    fn skeleton(&self) -> Vec<Vec<Vector3<f64>>> {
        let home = self.system.home();
        let Ok(q) = self.system.inputs_for_pose(&home, &self.geometry) else {
            return Vec::new();
        };
        let x = self.platform_pose(&q, Some(&home)).unwrap_or(home);
        let base = pose_of(&self.base);
        let platform = pose_of(&x);
        let tool = platform.transform_point(&Vector3::from(self.tool).into()).coords;
        let mut lines = self.system.skeleton(&x, &q, &self.geometry);
        if !lines.is_empty() {
            lines.push(vec![platform.translation.vector, tool]);
        }
        lines
            .iter()
            .map(|l| l.iter().map(|p| base.transform_point(&(*p).into()).coords).collect())
            .collect()
    }
    fn forward(&self, q: &[f64]) -> Result<Pose, KinError> {
        let x = self.platform_pose(q, None)?;
        Ok(self.tool_pose_of(&x))
    }
    fn forward_with_jacobian(&self, q: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        self.tool_pose_jacobian(q, None)
    }
    /// Newton starts from the platform coordinates of `near` (one residual evaluation when it is
    /// the pose at `q`).
    fn forward_with_jacobian_near(&self, q: &[f64], near: &Pose) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let seed = self.platform_of_tool(near);
        if seed.iter().all(|v| v.is_finite()) {
            self.tool_pose_jacobian(q, Some(&seed))
        } else {
            self.tool_pose_jacobian(q, None)
        }
    }
    /// The platform coordinates `X` (6 values).
    fn forward_solution(&self, q: &[f64]) -> Result<(Pose, Vec<f64>), KinError> {
        let x = self.platform_pose(q, None)?;
        Ok((self.tool_pose_of(&x), x.to_vec()))
    }
    /// At platform coordinates `rest = X` that satisfy the constraints at `q` (residual within the
    /// solver's tolerance): no Newton step, the conditioning checked as after a solve. Otherwise
    /// Newton from `pose` ([`Mechanism::forward_with_jacobian_near`]).
    fn forward_with_jacobian_at(&self, q: &[f64], pose: &Pose, rest: &[f64]) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        if let Ok(x) = <[f64; 6]>::try_from(rest) {
            if let Some(solved) = self.solved_at(q, x)? {
                return self.tool_pose_jacobian_at(q, solved);
            }
        }
        self.forward_with_jacobian_near(q, pose)
    }
    fn retract(&mut self, delta: &DVector<f64>) {
        let ng = self.geometry.len();
        for i in 0..ng.min(delta.len()) {
            self.geometry[i] += delta[i];
        }
        if self.frame_errors && delta.len() >= ng + 9 {
            for i in 0..3 {
                self.tool[i] += delta[ng + i];
            }
            for i in 0..6 {
                self.base[i] += delta[ng + 3 + i];
            }
        }
    }
    fn inverse(&self, target: &Pose, _seed: Option<&[f64]>) -> Result<Vec<f64>, KinError> {
        self.inverse_with_pose(target).map(|r| r.0)
    }
    fn box_clone(&self) -> Box<dyn Mechanism> {
        Box::new(self.clone())
    }
    fn geometry(&self) -> Option<Vec<f64>> {
        Some(self.geometry.iter().chain(&self.tool).chain(&self.base).copied().collect())
    }
    fn task(&self) -> Task {
        self.system.task()
    }
    fn sample_configurations(&self, n: usize, seed: u64) -> Option<Result<Vec<Vec<f64>>, KinError>> {
        use rand::SeedableRng;
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        Some(self.random_configurations(&mut rng, n))
    }
}

impl<C: ConstraintSystem> ClosedLoop<C> {
    /// Tool pose and its identification Jacobian at `q`, forward kinematics from `seed`.
    fn tool_pose_jacobian(&self, q: &[f64], seed: Option<&[f64; 6]>) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let solved = self.solve_platform(q, seed)?;
        self.tool_pose_jacobian_at(q, solved)
    }

    /// Tool pose and its identification Jacobian at a forward solution `(X, LU of F_X)` of `q`.
    fn tool_pose_jacobian_at(&self, q: &[f64], solved: ([f64; 6], Factors)) -> Result<(Pose, Matrix6xX<f64>), KinError> {
        let (x, dx) = self.sensitivity_at(q, solved)?;
        let pose = self.tool_pose_of(&x);
        let p = pose.translation.vector;
        let r = se3::rotation_matrix(&pose);
        let np = self.n_params_total();
        let ng = self.geometry.len();
        // Twist of the tool pose per unit of each of the 15 variables (X, tool, base), then the
        // chain rule: a geometric column is the X columns times dX/dθ.
        let per_x: [[f64; 6]; 6] = self.tool_twists(&x, 0, &p, &r);
        let mut jac = Matrix6xX::zeros(np);
        // Column-major 6-row columns of `jac` and `dx`, summed in the order i = 0..6.
        for (col, d) in jac.as_mut_slice().chunks_exact_mut(6).zip(dx.as_slice().chunks_exact(6)).take(ng) {
            for (t, &d) in per_x.iter().zip(d) {
                if d != 0.0 {
                    for (c, tk) in col.iter_mut().zip(t) {
                        *c += tk * d;
                    }
                }
            }
        }
        if self.frame_errors {
            let per_frame: [[f64; 6]; 9] = self.tool_twists(&x, 6, &p, &r);
            for (f, t) in per_frame.iter().enumerate() {
                for k in 0..6 {
                    jac[(k, ng + f)] = t[k];
                }
            }
        }
        Ok((pose, jac))
    }

    /// Spatial twists of the tool pose `(p, r)` per unit of the variables `from..from + N` of
    /// `(X, tool, base)` (15 in all), in one pass of `N`-lane dual numbers.
    fn tool_twists<const N: usize>(&self, x: &[f64; 6], from: usize, p: &Vector3<f64>, r: &Matrix3<f64>) -> [[f64; 6]; N] {
        let var = |v: f64, i: usize| {
            let d = DualSVec64::<N>::from_re(v);
            if i >= from && i < from + N {
                d.derivative(i - from)
            } else {
                d
            }
        };
        let xd: [DualSVec64<N>; 6] = std::array::from_fn(|i| var(x[i], i));
        let tool: [DualSVec64<N>; 3] = std::array::from_fn(|i| var(self.tool[i], 6 + i));
        let base: [DualSVec64<N>; 6] = std::array::from_fn(|i| var(self.base[i], 9 + i));
        let (pd, rd) = tool_pose_generic(&xd, &tool, &base);
        let lane = |d: &DualSVec64<N>, k: usize| d.eps.0.as_ref().map_or(0.0, |e| e[k]);
        std::array::from_fn(|k| {
            let dp = Vector3::new(lane(&pd[0], k), lane(&pd[1], k), lane(&pd[2], k));
            let dr = Matrix3::from_fn(|a, b| lane(&rd[a][b], k));
            let w = se3::unskew(&(dr * r.transpose()));
            let v = dp - w.cross(p);
            [v[0], v[1], v[2], w[0], w[1], w[2]]
        })
    }
}
