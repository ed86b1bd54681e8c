//! The configuration of a 6R arm with a spherical wrist, as robot controllers state it (ABB's
//! `confdata`): the quadrants of axes 1, 4 and 6 and three branch bits.
//!
//! * `cf1`, `cf4`, `cf6`: `⌊q/90°⌋` of axes 1, 4 and 6 (0 for 0…90°, −1 for −90…0°, …).
//! * `cfx = 4·b₁ + 2·b₂ + b₅`: `b₁` the wrist centre (the origin of joint 5's frame) behind axis 1
//!   (on the other side of axis 1 than at zero joint values, measured in axis 1's rotating
//!   frame); `b₂` the wrist centre behind the lower arm (on the other side of the line from axis 2
//!   to axis 3 than at zero joint values, seen along axis 2); `b₅` axis 5 negative.
//!
//! At zero joint values an arm built like the IRB 120 (upper arm up, forearm forward) is
//! `[0, 0, 0, 0]`.
use crate::error::KinError;
use crate::model::chain::{JointKind, SerialChain};
use nalgebra::Vector3;
use serde::Serialize;
use std::f64::consts::{FRAC_PI_2, PI};

/// An arm configuration: ABB's `confdata` `[cf1, cf4, cf6, cfx]`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct ArmConfiguration {
    /// Quadrant of axis 1.
    pub cf1: i32,
    /// Quadrant of axis 4.
    pub cf4: i32,
    /// Quadrant of axis 6.
    pub cf6: i32,
    /// Branch bits: 4 wrist centre behind axis 1, 2 behind the lower arm, 1 axis 5 negative.
    pub cfx: i32,
}

impl std::fmt::Display for ArmConfiguration {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "[{},{},{},{}]", self.cf1, self.cf4, self.cf6, self.cfx)
    }
}

/// KUKA's Status and Turn of a 6R arm's joint values: Status bit 0 the wrist centre behind
/// axis 1, bit 1 behind the lower arm, bit 2 axis 5 negative (the branch bits of
/// [`ArmConfiguration::cfx`] in another order); Turn bit `k` axis `k + 1` negative.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct StatusTurn {
    /// Status.
    pub s: i32,
    /// Turn.
    pub t: i32,
}

impl std::fmt::Display for StatusTurn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "S {}, T {}", self.s, self.t)
    }
}

/// A configuration a program states.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Configuration {
    /// ABB's `confdata`.
    Abb(ArmConfiguration),
    /// KUKA's Status and Turn.
    Kuka(StatusTurn),
}

impl std::fmt::Display for Configuration {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Configuration::Abb(c) => c.fmt(f),
            Configuration::Kuka(c) => c.fmt(f),
        }
    }
}

/// The quadrant `⌊q/90°⌋` of an angle (rad).
pub fn quadrant(q: f64) -> i32 {
    (q / FRAC_PI_2).floor() as i32
}

/// A 6R arm's configurations, computed on its (nominal) chain.
#[derive(Debug, Clone)]
pub struct ArmBranches {
    chain: SerialChain,
    /// The wrist centre's direction from axis 1 at zero, in axis 1's frame, across the axis.
    forward: Vector3<f64>,
    /// The sign of the elbow's side at zero.
    elbow: f64,
}

impl ArmBranches {
    /// The configurations of `chain`: `None` unless it has six revolute joints.
    pub fn new(chain: &SerialChain) -> Option<ArmBranches> {
        if chain.n_joints() != 6 || chain.joints().iter().any(|j| j.kind != JointKind::Revolute) {
            return None;
        }
        let mut b = ArmBranches {
            chain: chain.clone(),
            forward: Vector3::zeros(),
            elbow: 1.0,
        };
        let (forward, elbow) = b.sides(&[0.0; 6]).ok()?;
        let t = chain.joints()[0].twist;
        let axis = Vector3::new(t[3], t[4], t[5]).normalize();
        let across = forward - axis * axis.dot(&forward);
        if across.norm() < 1e-6 || elbow.abs() < 1e-9 {
            return None;
        }
        b.forward = across.normalize();
        b.elbow = elbow.signum();
        Some(b)
    }

    /// The wrist centre in axis 1's rotating frame, and the elbow's side (signed).
    fn sides(&self, q: &[f64]) -> Result<(Vector3<f64>, f64), KinError> {
        let g = self.chain.frames(q)?;
        let wrist = g[4].translation.vector;
        let in_axis1 = g[0].inverse_transform_point(&wrist.into()).coords;
        let (p2, p3) = (g[1].translation.vector, g[2].translation.vector);
        let t = self.chain.joints()[1].twist;
        let axis2 = g[1].rotation * Vector3::new(t[3], t[4], t[5]);
        let elbow = (p3 - p2).cross(&(wrist - p3)).dot(&axis2);
        Ok((in_axis1, elbow))
    }

    /// The configuration of joint values `q` (rad).
    pub fn of(&self, q: &[f64]) -> Result<ArmConfiguration, KinError> {
        let (w, elbow) = self.sides(q)?;
        let behind1 = w.dot(&self.forward) < 0.0;
        let behind2 = elbow * self.elbow < 0.0;
        Ok(ArmConfiguration {
            cf1: quadrant(q[0]),
            cf4: quadrant(q[3]),
            cf6: quadrant(q[5]),
            cfx: 4 * behind1 as i32 + 2 * behind2 as i32 + (q[4] < 0.0) as i32,
        })
    }

    /// KUKA's Status and Turn of joint values `q` (rad).
    pub fn status_turn(&self, q: &[f64]) -> Result<StatusTurn, KinError> {
        let c = self.of(q)?;
        let s = (c.cfx >> 2) & 1 | ((c.cfx >> 1) & 1) << 1 | (c.cfx & 1) << 2;
        let t = q.iter().enumerate().map(|(k, v)| ((*v < 0.0) as i32) << k).sum();
        Ok(StatusTurn { s, t })
    }

    /// The configuration of `q` in the flavour of `like`.
    pub fn configuration(&self, q: &[f64], like: &Configuration) -> Result<Configuration, KinError> {
        Ok(match like {
            Configuration::Abb(_) => Configuration::Abb(self.of(q)?),
            Configuration::Kuka(_) => Configuration::Kuka(self.status_turn(q)?),
        })
    }

    /// Whether `q` is on the configuration `c`.
    pub fn matches(&self, q: &[f64], c: &Configuration) -> bool {
        self.configuration(q, c).is_ok_and(|k| k == *c)
    }

    /// The joint values whose nearest whole-turn equivalents lie on `c` where the limits allow:
    /// the quadrants' middles (ABB), or ±180° on the side each Turn bit says (KUKA).
    pub fn reference(&self, c: &Configuration) -> Vec<f64> {
        let mid = |k: i32| (k as f64 + 0.5) * FRAC_PI_2;
        match c {
            Configuration::Abb(a) => vec![mid(a.cf1), 0.0, 0.0, mid(a.cf4), 0.0, mid(a.cf6)],
            Configuration::Kuka(k) => (0..6).map(|j| if (k.t >> j) & 1 == 1 { -PI } else { PI }).collect(),
        }
    }

    /// Starting points for the inverse kinematics on a stated configuration.
    pub fn seeds_for(&self, c: &Configuration, starts: &[Vec<f64>]) -> Vec<Vec<f64>> {
        match c {
            Configuration::Abb(a) => self.seeds(a, starts),
            Configuration::Kuka(k) => {
                // Each axis on the side its Turn bit says; the branch bits from the fixed values.
                let sign = |j: usize| if (k.t >> j) & 1 == 1 { -1.0 } else { 1.0 };
                let fixed = [
                    [0.8, 0.0, 0.0, 0.8, 0.8, 0.8],
                    [0.8, 0.5, 0.5, 0.8, 0.8, 0.8],
                    [0.8, 1.2, 2.0, 0.8, 0.8, 0.8],
                ];
                fixed
                    .iter()
                    .map(|f| f.to_vec())
                    .chain(starts.iter().filter(|s| s.len() == 6).cloned())
                    .map(|s| s.iter().enumerate().map(|(j, v)| sign(j) * v.abs()).collect())
                    .collect()
            }
        }
    }

    /// Starting points for the inverse kinematics on `c`: axes 1, 4 and 6 at their quadrants'
    /// middles and axis 5 on its side, the other axes from a few fixed values and from `starts`.
    pub fn seeds(&self, c: &ArmConfiguration, starts: &[Vec<f64>]) -> Vec<Vec<f64>> {
        let mid = |k: i32| (k as f64 + 0.5) * FRAC_PI_2;
        let q5 = if c.cfx & 1 == 1 { -0.7 } else { 0.7 };
        let mut out = Vec::new();
        let fixed = [
            [0.0, 0.0],
            [0.5, 0.5],
            [-0.5, 0.5],
            [0.5, -2.0],
            [-0.5, -2.0],
            [-1.2, 0.8],
            [1.2, -1.0],
        ];
        for [q2, q3] in fixed {
            out.push(vec![mid(c.cf1), q2, q3, mid(c.cf4), q5, mid(c.cf6)]);
        }
        for s in starts.iter().filter(|s| s.len() == 6) {
            out.push(vec![mid(c.cf1), s[1], s[2], mid(c.cf4), q5.signum() * s[4].abs(), mid(c.cf6)]);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::builtin::irb120;

    #[test]
    fn irb120_configurations() {
        let b = ArmBranches::new(&irb120()).unwrap();
        let d = |v: [f64; 6]| v.map(f64::to_radians);
        let c = |v| b.of(&d(v)).unwrap().to_string();
        assert_eq!(c([10.0, 0.0, 0.0, 10.0, 30.0, 10.0]), "[0,0,0,0]");
        assert_eq!(c([-10.0, 0.0, 0.0, 100.0, -30.0, -100.0]), "[-1,1,-2,1]");
        // The forearm folded past the stretched elbow (q3 < −76.95°): behind the lower arm.
        assert_eq!(c([10.0, 40.0, -100.0, 10.0, 30.0, 10.0]), "[0,0,0,2]");
        // The upper arm tilted far back with the forearm up: the wrist behind axis 1.
        assert_eq!(c([10.0, -60.0, -20.0, 10.0, 30.0, 10.0]), "[0,0,0,4]");
        let st = b.status_turn(&d([-10.0, -60.0, -20.0, 10.0, -30.0, 10.0])).unwrap();
        assert_eq!((st.s, st.t), (0b101, 0b10111));
    }
}
