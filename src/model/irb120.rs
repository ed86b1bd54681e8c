//! The ABB IRB 120 as a local-POE serial chain (nominal geometry).
//!
//! Joint axes z, y, y, x, y, x; d1 = 290 mm, a2 = 270 mm, a3 = 70 mm, d4 = 302 mm, d6 = 72 mm (the
//! vendor's data). At zero joint angles the upper arm points up and the forearm is horizontal
//! along +x. Each joint frame sits on its joint axis with the base orientation, so every joint
//! twist is a pure rotation `(0, axis)`:
//!
//! | dyad | initial pose `T_{j-1,j}(0)` | joint axis |
//! |---|---|---|
//! | 0-1 | identity (joint 1 on the base z axis) | z |
//! | 1-2 | Trans(0, 0, 290) | y |
//! | 2-3 | Trans(0, 0, 270) | y |
//! | 3-4 | Trans(0, 0, 70) | x |
//! | 4-5 | Trans(302, 0, 0) | y |
//! | 5-6 | Trans(72, 0, 0) | x |
//! | 6-T | the tool (identity: the flange) | |
use super::chain::{ChainJoint, SerialChain};
use crate::se3::{self, Pose};
use nalgebra::Vector3;

/// Joint limits from the product specification (deg): ±165, ±110, −110…+70, ±160, ±120, ±400.
pub const JOINT_LIMITS_DEG: [(f64, f64); 6] = [
    (-165.0, 165.0),
    (-110.0, 110.0),
    (-110.0, 70.0),
    (-160.0, 160.0),
    (-120.0, 120.0),
    (-400.0, 400.0),
];

/// Nominal IRB 120 with the tool frame at the flange and the base frame at the robot base, with
/// the joint limits of [`JOINT_LIMITS_DEG`].
pub fn nominal() -> SerialChain {
    let axes = [Vector3::z(), Vector3::y(), Vector3::y(), Vector3::x(), Vector3::y(), Vector3::x()];
    let joints = axes
        .iter()
        .zip(JOINT_LIMITS_DEG)
        .enumerate()
        .map(|(k, (axis, (lo, hi)))| {
            let mut j = ChainJoint::revolute(format!("q{}", k + 1), *axis);
            j.limits = Some((lo.to_radians(), hi.to_radians()));
            j
        })
        .collect();
    let initial = vec![
        Pose::identity(),
        se3::translation(0.0, 0.0, 290.0),
        se3::translation(0.0, 0.0, 270.0),
        se3::translation(0.0, 0.0, 70.0),
        se3::translation(302.0, 0.0, 0.0),
        se3::translation(72.0, 0.0, 0.0),
    ];
    SerialChain::new("irb120", joints, initial, Pose::identity())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Mechanism;
    use approx::assert_relative_eq;

    #[test]
    fn zero_pose_flange_position() {
        let t = nominal().forward(&[0.0; 6]).unwrap();
        assert_relative_eq!(t.translation.vector, Vector3::new(374.0, 0.0, 630.0), epsilon = 1e-12);
    }
}
