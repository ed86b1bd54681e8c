//! A cheap test that a limb cannot reach a point at all, run before its inverse kinematics: a
//! target outside a limb's reach otherwise costs Newton from home and both continuations (about
//! ten times a solve that succeeds) before it is given up.
//!
//! The test is conservative: it only answers for a limb starting on the base whose joints all
//! turn about axes through their local origins (revolute twists without a linear part; a
//! prismatic or offset joint makes it answer "maybe"), ignores joint limits and couplings (both
//! only shrink the reach), and declares a miss only by more than [`MISS_MARGIN`], far above the
//! round-off of the bounds and the closure tolerance: a target the solver could reach is never
//! rejected.
use super::*;

/// Smallest distance (mm) by which a limb must clearly miss its target to be rejected unsolved.
const MISS_MARGIN: f64 = 1e-6;

/// Bounds `lo ≤ |p − centre| ≤ hi` of a set of points.
#[derive(Debug, Clone, Copy)]
struct Shell {
    centre: Vector3<f64>,
    lo: f64,
    hi: f64,
}

impl LimbMechanism {
    /// The distance by which limb `i`'s end clearly misses the platform at `x` for every value of
    /// its joints (the end's origin must reach the platform point of a point end, the platform
    /// origin of a frame end), or `None` when it may reach it (see the [module docs](self)).
    pub(super) fn limb_misses(&self, i: usize, x: &Pose) -> Option<f64> {
        let l = &self.limbs[i];
        if l.start.is_some() || l.end_on.is_some() {
            return None;
        }
        let target = match &l.end {
            LimbEnd::Point(a) => x * nalgebra::Point3::from(*a),
            LimbEnd::Frame => nalgebra::Point3::from(x.translation.vector),
        };
        let joints = l.chain.joints();
        let placements = l.chain.initial_poses();
        let n = joints.len();
        // Turning about an axis through the local origin, by a unit axis (else no answer).
        let axis_of = |j: usize| {
            let s = &joints[j].twist;
            let w = Vector3::new(s[3], s[4], s[5]);
            (joints[j].kind == JointKind::Revolute && s[..3] == [0.0; 3] && w.norm() > 0.0).then(|| w.normalize())
        };
        if n == 0 {
            return None;
        }
        // The end's origin in the frame after the last joint's motion: one point.
        let mut shell = Shell {
            centre: placements[n].translation.vector,
            lo: 0.0,
            hi: 0.0,
        };
        // Fold joints n−1 … 1: a turn about the local origin keeps |p|, so the points after joint
        // j lie in a shell about the origin of its frame, i.e. about its placement's origin in
        // the frame before it.
        for j in (1..n).rev() {
            axis_of(j)?;
            let d = shell.centre.norm();
            shell = Shell {
                centre: placements[j].translation.vector,
                lo: (shell.lo - d).max(d - shell.hi).max(0.0),
                hi: d + shell.hi,
            };
        }
        // Joint 0 turns the shell's centre on a circle about its axis: the distances from the
        // target (in joint 0's frame) to that circle's points run from `near` to `far`.
        let u = axis_of(0)?;
        let w = placements[0].inverse_transform_point(&target).coords;
        let c = shell.centre;
        let (hw, hc) = (u.dot(&w), u.dot(&c));
        let (rw, rc) = ((w - u * hw).norm(), (c - u * hc).norm());
        let dh = hw - hc;
        let near = ((rw - rc).powi(2) + dh * dh).sqrt();
        let far = ((rw + rc).powi(2) + dh * dh).sqrt();
        let gap = (shell.lo - far).max(near - shell.hi);
        (gap > MISS_MARGIN * (1.0 + w.norm() + c.norm() + shell.hi)).then_some(gap)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::limbs::limbs_from_text as limbs;

    /// Every limb reaches where the machine goes (never a miss there), and a platform lifted far
    /// beyond the rods' length is a miss of every limb by about the lift.
    #[test]
    fn a_limb_misses_only_what_it_cannot_reach() {
        let m = limbs(include_str!("../../../examples/models/hexapod-6rus.toml"));
        for q in m.sample_configurations(50, 3).unwrap().unwrap() {
            let x = m.forward_full(&q).unwrap().0;
            for i in 0..m.limbs.len() {
                assert_eq!(m.limb_misses(i, &x), None, "limb {i}");
            }
        }
        let far = Pose::from_parts(nalgebra::Translation3::new(0.0, 0.0, 1000.0), m.home.rotation);
        for i in 0..m.limbs.len() {
            let gap = m.limb_misses(i, &far).expect("a miss");
            assert!(gap > 600.0 && gap < 800.0, "limb {i}: {gap}");
        }
    }
}
