//! SE(3) and se(3): hat, vee, exponential, logarithm, adjoints.
//!
//! # Conventions (written once, used everywhere in kinecal)
//!
//! * A pose is an [`Pose`] (`nalgebra::Isometry3<f64>`): `T = [R p; 0 1]`, mapping points of the
//!   child frame into the parent frame, `x_parent = R·x_child + p`.
//! * A twist is a 6-vector in the order **(v, ω)** — linear part first, as in both seed papers
//!   (`s = [0 1 0 0 0 0]ᵀ` is a prismatic joint along y, `s = [0 0 0 1 0 0]ᵀ` a revolute about x).
//!   `hat(ξ) = [[ω̂, v], [0, 0]]`.
//! * `exp(hat(ξ))` is computed in closed form (Rodrigues and the `V` matrix); `log` goes through a
//!   unit quaternion, `θ = 2·atan2(|q_xyz|, q_w)`, which is well conditioned for every angle: near
//!   the identity it degrades to the series `ω ≈ 2·q_xyz`, and at a half turn (`trace R = −1`,
//!   the special case of eq. (38) in the 3T1R paper) the axis comes from the quaternion's vector
//!   part without any division by `sin θ`.
//! * The adjoint `Ad_T = [[R, p̂R], [0, R]]` maps twists: `hat(Ad_T ξ) = T·hat(ξ)·T⁻¹`.
//! * A *spatial* (left) perturbation `T' = exp(hat(δ))·T` is what the local-POE error model of the
//!   3T1R paper, eq. (17)–(19), produces: `log(T'·T⁻¹) = δ`.
//! * A *pose error* for reporting and for weighted residuals is `(p' − p, log(R'·Rᵀ))`: a position
//!   difference in length units and a rotation vector in radians, both in the parent frame. For a
//!   spatial perturbation `δ = (v, ω)` its first-order value is `(v − p̂·ω, ω)`
//!   ([`spatial_to_pose_error`]).
use nalgebra::{Isometry3, Matrix3, Matrix6, Matrix6xX, Quaternion, Translation3, UnitQuaternion, Vector3, Vector6};

/// A rigid-body pose, an element of SE(3).
pub type Pose = Isometry3<f64>;
/// A twist `(v, ω)`, an element of se(3) in vector form.
pub type Twist = Vector6<f64>;

/// The skew-symmetric matrix `ω̂` with `ω̂·x = ω × x`.
pub fn skew(w: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -w.z, w.y, w.z, 0.0, -w.x, -w.y, w.x, 0.0)
}

/// The vector `ω` of a skew-symmetric matrix (the inverse of [`skew`]); only the skew part of `m` counts.
pub fn unskew(m: &Matrix3<f64>) -> Vector3<f64> {
    Vector3::new(m[(2, 1)] - m[(1, 2)], m[(0, 2)] - m[(2, 0)], m[(1, 0)] - m[(0, 1)]) * 0.5
}

/// `hat(ξ)`: the 4×4 matrix of a twist `(v, ω)`.
pub fn hat(xi: &Twist) -> nalgebra::Matrix4<f64> {
    let mut m = nalgebra::Matrix4::zeros();
    let w = Vector3::new(xi[3], xi[4], xi[5]);
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&skew(&w));
    m[(0, 3)] = xi[0];
    m[(1, 3)] = xi[1];
    m[(2, 3)] = xi[2];
    m
}

/// `vee(M)`: the twist `(v, ω)` of a 4×4 matrix of se(3) (inverse of [`hat`]).
pub fn vee(m: &nalgebra::Matrix4<f64>) -> Twist {
    let w = unskew(&m.fixed_view::<3, 3>(0, 0).into_owned());
    Twist::new(m[(0, 3)], m[(1, 3)], m[(2, 3)], w.x, w.y, w.z)
}

/// Linear part of a twist.
pub fn lin(xi: &Twist) -> Vector3<f64> {
    Vector3::new(xi[0], xi[1], xi[2])
}

/// Angular part of a twist.
pub fn ang(xi: &Twist) -> Vector3<f64> {
    Vector3::new(xi[3], xi[4], xi[5])
}

/// Build a twist from its linear and angular parts.
pub fn twist(v: &Vector3<f64>, w: &Vector3<f64>) -> Twist {
    Twist::new(v.x, v.y, v.z, w.x, w.y, w.z)
}

/// Rotation exponential `exp(ω̂)` as a unit quaternion (exact for every angle).
pub fn so3_exp(w: &Vector3<f64>) -> UnitQuaternion<f64> {
    let theta = w.norm();
    let half = 0.5 * theta;
    // sin(θ/2)/θ with its series near zero.
    let k = if theta < 1e-6 {
        0.5 - theta * theta / 48.0
    } else {
        half.sin() / theta
    };
    UnitQuaternion::new_unchecked(Quaternion::new(half.cos(), k * w.x, k * w.y, k * w.z))
}

/// Rotation logarithm: the rotation vector `ω` (|ω| ≤ π) of a unit quaternion.
pub fn so3_log(q: &UnitQuaternion<f64>) -> Vector3<f64> {
    let (mut w, mut v) = (q.w, q.imag());
    if w < 0.0 {
        w = -w;
        v = -v;
    }
    let s = v.norm();
    let theta = 2.0 * s.atan2(w);
    // θ / sin(θ/2) with sin(θ/2) = s; series when s is tiny (w ≈ 1).
    let k = if s < 1e-8 { 2.0 / w } else { theta / s };
    v * k
}

/// The `V` matrix of the SE(3) exponential (left Jacobian of SO(3)): `p = V(ω)·v`.
pub fn so3_left_jacobian(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let t = t2.sqrt();
    let wx = skew(w);
    // a = (1 − cos t)/t² written as ½·(sin(t/2)/(t/2))² (no cancellation); b = (t − sin t)/t³ by
    // its Taylor series below 0.01 rad, where the closed form loses digits.
    let a = if t < 1e-8 {
        0.5
    } else {
        let s = (0.5 * t).sin() / (0.5 * t);
        0.5 * s * s
    };
    let b = if t < 1e-2 {
        1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0 - t2 * t2 * t2 / 362880.0
    } else {
        (t - t.sin()) / (t2 * t)
    };
    Matrix3::identity() + wx * a + wx * wx * b
}

/// The inverse of [`so3_left_jacobian`]: `v = V(ω)⁻¹·p` (the `A*` matrix of the 3T1R paper, eq. (38)).
pub fn so3_left_jacobian_inv(w: &Vector3<f64>) -> Matrix3<f64> {
    let t2 = w.norm_squared();
    let t = t2.sqrt();
    let wx = skew(w);
    // c = (1 − (t/2)·cot(t/2))/t², by its Taylor series below 0.01 rad.
    let c = if t < 1e-2 {
        1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0 + t2 * t2 * t2 / 1209600.0
    } else {
        let h = 0.5 * t;
        (1.0 - h * h.cos() / h.sin()) / t2
    };
    Matrix3::identity() - wx * 0.5 + wx * wx * c
}

/// The SE(3) exponential `exp(hat(ξ))` of a twist `(v, ω)`.
pub fn exp(xi: &Twist) -> Pose {
    let w = ang(xi);
    let p = so3_left_jacobian(&w) * lin(xi);
    Isometry3::from_parts(Translation3::from(p), so3_exp(&w))
}

/// The SE(3) logarithm: the twist `(v, ω)` with `exp(hat(ξ)) = T` and `|ω| ≤ π`.
pub fn log(t: &Pose) -> Twist {
    let w = so3_log(&t.rotation);
    let v = so3_left_jacobian_inv(&w) * t.translation.vector;
    twist(&v, &w)
}

/// Exponential of a joint motion `exp(hat(s)·q)`.
///
/// For the unit twists of joints (a revolute joint: `|ω| = 1`; a prismatic one: `ω = 0`) in closed
/// form from the rotation alone, `p = (I − R)·(ω × v) + ω·(ω·v)·q` (Murray, Li & Sastry, eq. 2.36),
/// with one `sin_cos`; any other twist through [`exp`].
pub fn exp_joint(s: &Twist, q: f64) -> Pose {
    let (v, w) = (lin(s), ang(s));
    let n2 = w.norm_squared();
    if n2 == 0.0 {
        return Isometry3::from_parts(Translation3::from(v * q), UnitQuaternion::identity());
    }
    if (n2 - 1.0).abs() > 1e-12 {
        return exp(&(s * q));
    }
    let (sn, cs) = (0.5 * q).sin_cos();
    let r = UnitQuaternion::new_unchecked(Quaternion::new(cs, sn * w.x, sn * w.y, sn * w.z));
    let c = w.cross(&v);
    let p = c - r * c + w * (w.dot(&v) * q);
    Isometry3::from_parts(Translation3::from(p), r)
}

/// An angle difference wrapped to `[−π, π)` (rad).
pub fn wrap_angle(a: f64) -> f64 {
    (a + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI
}

/// The yaw `atan2(R₁₀, R₀₀)` of `b` minus that of `a` (rad, in (−π, π]): the rotation about the
/// base z-axis a 3T1R machine commands (its tilts are parasitic).
pub fn yaw_difference(a: &Pose, b: &Pose) -> f64 {
    let yaw = |p: &Pose| {
        let x = p.rotation * nalgebra::Vector3::x();
        x.y.atan2(x.x)
    };
    let d = yaw(b) - yaw(a);
    d.sin().atan2(d.cos())
}

/// The adjoint matrix `Ad_T = [[R, p̂R], [0, R]]` in (v, ω) order.
pub fn adjoint(t: &Pose) -> Matrix6<f64> {
    let r = t.rotation.to_rotation_matrix().into_inner();
    let p = t.translation.vector;
    let mut m = Matrix6::zeros();
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&r);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(skew(&p) * r));
    m
}

/// `Ad_T·ξ` without forming the matrix: `(R·v + p × R·ω, R·ω)`.
pub fn adjoint_apply(t: &Pose, xi: &Twist) -> Twist {
    let rw = t.rotation * ang(xi);
    let rv = t.rotation * lin(xi);
    twist(&(rv + t.translation.vector.cross(&rw)), &rw)
}

/// The small adjoint `ad_ξ = [[ω̂, v̂], [0, ω̂]]`: `ad_ξ η` is the Lie bracket `[ξ, η]`.
pub fn ad(xi: &Twist) -> Matrix6<f64> {
    let mut m = Matrix6::zeros();
    let wx = skew(&ang(xi));
    m.fixed_view_mut::<3, 3>(0, 0).copy_from(&wx);
    m.fixed_view_mut::<3, 3>(3, 3).copy_from(&wx);
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&skew(&lin(xi)));
    m
}

/// The right Jacobian of the exponential, `exp(ξ + δ) ≈ exp(ξ)·exp(J_r(ξ)·δ)` to first order in
/// `δ`: the series `Σ_k (−ad_ξ)^k / (k + 1)!`, summed until its terms no longer change the sum
/// (at most 40 terms; for the rotations of a calibration, `|ω| ≪ π`, a few dozen at most).
pub fn right_jacobian(xi: &Twist) -> Matrix6<f64> {
    let m = -ad(xi);
    let mut sum = Matrix6::identity();
    let mut term = Matrix6::identity();
    for k in 1..40 {
        term = term * m / (k as f64 + 1.0);
        let size = term.abs().max();
        sum += term;
        if size <= 1e-18 * sum.abs().max() {
            break;
        }
    }
    sum
}

/// Pose error `(p_a − p_b, log(R_a·R_bᵀ))` of `a` relative to `b`, both expressed in the common
/// parent frame: position difference (length unit of the poses) and rotation vector (rad).
pub fn pose_error(a: &Pose, b: &Pose) -> Vector6<f64> {
    let dp = a.translation.vector - b.translation.vector;
    let dw = so3_log(&(a.rotation * b.rotation.inverse()));
    twist(&dp, &dw)
}

/// The 6×6 map from a spatial perturbation `δ` of a pose with position `p` to the first-order pose
/// error `(δp, δφ) = (v − p̂ω, ω)`.
pub fn spatial_to_pose_error(p: &Vector3<f64>) -> Matrix6<f64> {
    let mut m = Matrix6::identity();
    m.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-skew(p)));
    m
}

/// `a · b` for a 6×6 matrix and a 6 × n one, column by column with fixed-size products: for the
/// many small products of a linearisation, far cheaper than a general (blocked, threaded) matrix
/// multiplication.
pub fn mul6(a: &Matrix6<f64>, b: &Matrix6xX<f64>) -> Matrix6xX<f64> {
    let mut out = Matrix6xX::zeros(b.ncols());
    for (mut o, c) in out.column_iter_mut().zip(b.column_iter()) {
        let v: Vector6<f64> = c.into_owned();
        o.copy_from(&(a * v));
    }
    out
}

/// A pose from a translation and a rotation vector.
pub fn pose_from_parts(p: Vector3<f64>, rotvec: Vector3<f64>) -> Pose {
    Isometry3::from_parts(Translation3::from(p), so3_exp(&rotvec))
}

/// A pure translation.
pub fn translation(x: f64, y: f64, z: f64) -> Pose {
    Isometry3::translation(x, y, z)
}

/// Rotation matrix of a pose.
pub fn rotation_matrix(t: &Pose) -> Matrix3<f64> {
    t.rotation.to_rotation_matrix().into_inner()
}

/// [`pose_from_matrix`] for a matrix known to be a rotation to round-off (one built from angles):
/// no iterative projection onto the rotations, only the quaternion of the matrix.
pub fn pose_from_rotation(r: &Matrix3<f64>, p: &Vector3<f64>) -> Pose {
    let rot = nalgebra::Rotation3::from_matrix_unchecked(*r);
    Isometry3::from_parts(Translation3::from(*p), UnitQuaternion::from_rotation_matrix(&rot))
}

/// The pose with rotation matrix `r` (projected onto the nearest rotation, so a matrix read from
/// a file or estimated from data may be slightly off) and translation `p`.
pub fn pose_from_matrix(r: &Matrix3<f64>, p: &Vector3<f64>) -> Pose {
    // Müller et al.'s iteration (nalgebra's `from_matrix`) with a bound on its steps: a rotation
    // slightly off converges in a few, a matrix of garbage (a corrupted file) must not loop forever.
    let rot = nalgebra::Rotation3::from_matrix_eps(r, f64::EPSILON, 100, nalgebra::Rotation3::identity());
    Isometry3::from_parts(Translation3::from(*p), UnitQuaternion::from_rotation_matrix(&rot))
}

/// X-Y-Z Euler angles `(α, β, γ)` of a rotation matrix, `R = Rot(x,α)·Rot(y,β)·Rot(z,γ)` (the
/// convention of closed-loop platform coordinates and model-file poses), `β` in `[−π/2, π/2]`.
pub fn euler_xyz(r: &Matrix3<f64>) -> [f64; 3] {
    let b = r[(0, 2)].clamp(-1.0, 1.0).asin();
    let a = (-r[(1, 2)]).atan2(r[(2, 2)]);
    let g = (-r[(0, 1)]).atan2(r[(0, 0)]);
    [a, b, g]
}

/// Roll, pitch, yaw of a rotation, `R = Rz(yaw)·Ry(pitch)·Rx(roll)` (the convention of model
/// files and of URDF), conditioned for every pitch: pitch from `atan2` (an `asin` loses half the
/// digits near ±90°), and near ±90° (gimbal lock), where only `roll ∓ yaw` is well determined,
/// yaw fitted to the roll found when that rebuilds the rotation better. Rebuilt with
/// `UnitQuaternion::from_euler_angles(roll, pitch, yaw)` it gives `q` back to ~1e-15 rad.
pub fn rpy(q: &UnitQuaternion<f64>) -> [f64; 3] {
    let m = q.to_rotation_matrix().into_inner();
    let pitch = (-m[(2, 0)]).atan2((m[(0, 0)] * m[(0, 0)] + m[(1, 0)] * m[(1, 0)]).sqrt());
    let roll = m[(2, 1)].atan2(m[(2, 2)]);
    let general = [roll, pitch, m[(1, 0)].atan2(m[(0, 0)])];
    // Near the lock: yaw from the first two rows of the second column given roll and pitch,
    // (r01, r11) = [[a, −b], [b, a]]·(cos yaw, sin yaw) with a = sin pitch·sin roll, b = cos roll,
    // so an imprecise roll only leaves an error scaled by cos pitch.
    let (a, b) = (pitch.sin() * roll.sin(), roll.cos());
    let locked = [roll, pitch, (a * m[(1, 1)] - b * m[(0, 1)]).atan2(a * m[(0, 1)] + b * m[(1, 1)])];
    let gap = |a: &[f64; 3]| so3_log(&(UnitQuaternion::from_euler_angles(a[0], a[1], a[2]).inverse() * q)).norm();
    if gap(&locked) < gap(&general) {
        locked
    } else {
        general
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn joint_exponential_in_closed_form_is_the_exponential() {
        let axis = Vector3::new(0.3, -0.5, 0.8).normalize();
        let point = Vector3::new(120.0, -40.0, 75.0);
        let revolute = twist(&(-axis.cross(&point)), &axis);
        let screw = twist(&(-axis.cross(&point) + axis * 2.5), &axis);
        let prismatic = twist(&axis, &Vector3::zeros());
        for s in [revolute, screw, prismatic] {
            for q in [0.0, 1e-9, 0.3, -2.0, 3.1, 7.5, -40.0] {
                let (a, b) = (exp_joint(&s, q), exp(&(s * q)));
                assert!(
                    (a.translation.vector - b.translation.vector).norm() < 1e-11 * (1.0 + q.abs() * 200.0),
                    "{q}"
                );
                assert!(a.rotation.angle_to(&b.rotation) < 1e-13, "{q}");
            }
        }
    }

    #[test]
    fn euler_xyz_rebuilds_the_rotation() {
        for (a, b, g) in [(0.3, -0.7, 2.9), (-3.0, 1.5, 0.1), (0.0, 0.0, 0.0), (1.0, -1.2, -2.0)] {
            let r = UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a)
                * UnitQuaternion::from_axis_angle(&Vector3::y_axis(), b)
                * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), g);
            let e = euler_xyz(r.to_rotation_matrix().matrix());
            assert_relative_eq!(e[0], a, epsilon = 1e-12);
            assert_relative_eq!(e[1], b, epsilon = 1e-12);
            assert_relative_eq!(e[2], g, epsilon = 1e-12);
        }
    }

    #[test]
    fn rpy_rebuilds_the_rotation_at_and_near_gimbal_lock() {
        for pitch in [
            0.3,
            1.0,
            std::f64::consts::FRAC_PI_2,
            -std::f64::consts::FRAC_PI_2,
            std::f64::consts::FRAC_PI_2 - 3e-8,
            -std::f64::consts::FRAC_PI_2 + 5e-12,
        ] {
            for (roll, yaw) in [(0.0, 0.0), (0.4, -1.1), (-2.9, 3.0)] {
                let q = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
                let a = rpy(&q);
                let back = UnitQuaternion::from_euler_angles(a[0], a[1], a[2]);
                assert!(so3_log(&(back.inverse() * q)).norm() < 1e-14, "{roll} {pitch} {yaw}: {a:?}");
            }
        }
    }

    #[test]
    fn right_jacobian_is_the_derivative_of_exp_near_0_and_near_pi() {
        // exp(ξ + h·e_i) = exp(ξ)·exp(h·J_r(ξ)·e_i) to first order: central differences of
        // log(exp(ξ)⁻¹·exp(ξ ± h·e_i)).
        for xi in [
            Twist::new(0.3, -0.2, 0.1, 1e-4, -2e-4, 3e-4),
            Twist::new(80.0, -20.0, 5.0, 0.02, -0.01, 0.03),
            Twist::new(10.0, 5.0, -7.0, 1.7, -1.9, 1.2),
        ] {
            let jr = right_jacobian(&xi);
            let inv = exp(&xi).inverse();
            let h = 1e-6;
            for i in 0..6 {
                let mut e = Twist::zeros();
                e[i] = h;
                let d = (log(&(inv * exp(&(xi + e)))) - log(&(inv * exp(&(xi - e))))) / (2.0 * h);
                let col = jr.column(i);
                let err = (d - col).amax();
                assert!(err < 1e-6 * (1.0 + xi.amax()), "ξ = {xi:?}, column {i}: {err:e}");
            }
        }
    }

    #[test]
    fn hat_vee_roundtrip() {
        let xi = Twist::new(1.0, -2.0, 3.0, 0.4, -0.5, 0.6);
        assert_relative_eq!(vee(&hat(&xi)), xi, epsilon = 1e-15);
    }

    #[test]
    fn exp_matches_matrix_series() {
        let xi = Twist::new(0.3, -0.2, 0.5, 0.7, -0.4, 0.2);
        let m = hat(&xi);
        let mut term = nalgebra::Matrix4::identity();
        let mut sum = nalgebra::Matrix4::identity();
        for k in 1..40 {
            term = term * m / k as f64;
            sum += term;
        }
        assert_relative_eq!(exp(&xi).to_homogeneous(), sum, epsilon = 1e-12);
    }

    /// A rotation slightly off is projected back; a matrix of garbage gives an answer (it used
    /// to loop forever on a corrupted reflector coordinate).
    #[test]
    fn pose_from_matrix_projects_and_always_returns() {
        let q = UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0);
        let r = q.to_rotation_matrix().into_inner() + Matrix3::from_element(1e-9);
        let t = pose_from_matrix(&r, &Vector3::new(1.0, 2.0, 3.0));
        assert!(t.rotation.angle_to(&q) < 1e-8);
        for bad in [1e156, f64::NAN, f64::INFINITY] {
            let mut m = Matrix3::identity();
            m[(1, 2)] = bad;
            let _ = pose_from_matrix(&m, &Vector3::zeros());
        }
    }

    #[test]
    fn adjoint_is_conjugation() {
        let t = exp(&Twist::new(0.3, -1.2, 0.5, 0.7, -0.4, 1.2));
        let xi = Twist::new(0.1, 0.2, -0.3, -0.5, 0.25, 0.4);
        let lhs = hat(&(adjoint(&t) * xi));
        let rhs = t.to_homogeneous() * hat(&xi) * t.inverse().to_homogeneous();
        assert_relative_eq!(lhs, rhs, epsilon = 1e-12);
    }

    #[test]
    fn half_turn_log() {
        for axis in [Vector3::x(), Vector3::y(), Vector3::new(1.0, 2.0, -2.0).normalize()] {
            let xi = twist(&Vector3::new(0.5, -1.0, 2.0), &(axis * std::f64::consts::PI));
            let t = exp(&xi);
            let back = exp(&log(&t));
            assert_relative_eq!(back.to_homogeneous(), t.to_homogeneous(), epsilon = 1e-12);
            assert_relative_eq!(ang(&log(&t)).norm(), std::f64::consts::PI, epsilon = 1e-12);
        }
    }
}
