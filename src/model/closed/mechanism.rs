//! [`ClosedLoop`] as a [`Mechanism`]: forward kinematics with the identification Jacobian,
//! inverse kinematics, retraction of the geometry, sampling of configurations.
use super::*;
use num_dual::Dual64;

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
        let (x, dx) = self.pose_sensitivity(q, seed)?;
        let pose = self.tool_pose_of(&x);
        let p = pose.translation.vector;
        let r = se3::rotation_matrix(&pose);
        let np = self.n_params_total();
        let ng = self.geometry.len();
        let mut jac = Matrix6xX::zeros(np);
        for j in 0..np {
            let xd: [Dual64; 6] = std::array::from_fn(|i| Dual64::new(x[i], dx[(i, j)]));
            let tool: [Dual64; 3] =
                std::array::from_fn(|i| Dual64::new(self.tool[i], if self.frame_errors && j == ng + i { 1.0 } else { 0.0 }));
            let base: [Dual64; 6] =
                std::array::from_fn(|i| Dual64::new(self.base[i], if self.frame_errors && j == ng + 3 + i { 1.0 } else { 0.0 }));
            let (pd, rd) = tool_pose_generic(&xd, &tool, &base);
            let dp = Vector3::new(pd[0].eps, pd[1].eps, pd[2].eps);
            let dr = Matrix3::from_fn(|a, b| rd[a][b].eps);
            let w = se3::unskew(&(dr * r.transpose()));
            let v = dp - w.cross(&p);
            for k in 0..3 {
                jac[(k, j)] = v[k];
                jac[(3 + k, j)] = w[k];
            }
        }
        Ok((pose, jac))
    }
}
