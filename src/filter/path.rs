//! The path between two corrected targets. The nominal controller moves the machine along a
//! straight line between the corrected targets `T'_a`, `T'_b` (its own interpolation, in its
//! own coordinates), computing joint values with its nominal inverse kinematics; the real
//! machine, as the calibrated model describes it, follows another path, whose distance from the
//! commanded line `T_a`–`T_b` grows with the line's length. [`Path::deviation`] samples it;
//! [`Path::split`] bisects the commanded line, correcting each added point, until every piece
//! stays within a tolerance.
use super::{correct_one, Corrected, FilterModels, Target};
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::Vector3;

/// Samples inside each straight move when its deviation is judged.
pub const SAMPLES: usize = 16;
/// Bisections of one move at most (2^10 pieces).
const MAX_DEPTH: usize = 10;

/// A controller's interpolation between two poses at a fraction of the move.
pub type Interpolation<'a> = &'a dyn Fn(&Pose, &Pose, f64) -> Pose;

/// A point of a move: the original target, its correction, and its fraction of the move.
#[derive(Debug, Clone)]
pub struct PathPoint {
    /// The original target (base frame, the program's tool).
    pub original: Pose,
    /// Its correction.
    pub corrected: Corrected,
    /// Where it lies on the original move, 0 at the start, 1 at the end.
    pub fraction: f64,
}

/// Both models with one tool and the controller's interpolation.
pub struct Path<'a> {
    /// The filter's models.
    pub models: &'a FilterModels,
    /// The calibrated model, base frame, the program's tool.
    pub cal: &'a dyn Mechanism,
    /// The nominal model, the same.
    pub nom: &'a dyn Mechanism,
    /// The tool.
    pub tool: Pose,
    /// The controller's straight move.
    pub interp: Interpolation<'a>,
    /// Starting points of the inverse kinematics.
    pub starts: &'a [Vec<f64>],
}

/// Distance of `p` from the segment `a`–`b`.
fn to_segment(p: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ab = b - a;
    let l2 = ab.norm_squared();
    let s = if l2 > 0.0 { ((p - a).dot(&ab) / l2).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * s)).norm()
}

impl Path<'_> {
    /// The largest distance (mm) of the calibrated model's tool point from the commanded
    /// segment `a.original`–`b.original` while the nominal controller moves along its straight
    /// line between the corrected targets, at [`SAMPLES`] points; an error when the nominal
    /// inverse kinematics loses the line.
    pub fn deviation(&self, a: &PathPoint, b: &PathPoint) -> Result<f64, String> {
        let (pa, pb) = (a.original.translation.vector, b.original.translation.vector);
        let mut q = a.corrected.q.clone();
        let mut worst = 0.0f64;
        for i in 1..SAMPLES {
            let s = i as f64 / SAMPLES as f64;
            let t = (self.interp)(&a.corrected.pose, &b.corrected.pose, s);
            let next = self
                .nom
                .inverse(&t, Some(&q))
                .map_err(|e| format!("the nominal controller loses the move: {e}"))?;
            let reached = self.nom.forward(&next).map_err(|e| e.to_string())?;
            if (reached.translation.vector - t.translation.vector).norm() > 1e-6 {
                return Err("the nominal controller loses the move between the corrected targets".into());
            }
            q = next;
            let p = self.cal.forward(&q).map_err(|e| e.to_string())?.translation.vector;
            worst = worst.max(to_segment(&p, &pa, &pb));
        }
        Ok(worst)
    }

    /// The points to add between `a` and `b` (in order) so that each piece's
    /// [`Path::deviation`] is at most `tolerance` mm: the commanded move bisected, each
    /// midpoint corrected; and the largest deviation of a piece. An error when the move cannot
    /// be held within 2^10 pieces.
    pub fn split(&self, a: &PathPoint, b: &PathPoint, tolerance: f64) -> Result<(Vec<PathPoint>, f64), String> {
        let mut out = Vec::new();
        let mut worst = 0.0;
        self.split_into(a, b, tolerance, 0, &mut out, &mut worst)?;
        Ok((out, worst))
    }

    fn split_into(
        &self,
        a: &PathPoint,
        b: &PathPoint,
        tolerance: f64,
        depth: usize,
        out: &mut Vec<PathPoint>,
        worst: &mut f64,
    ) -> Result<(), String> {
        let d = self.deviation(a, b)?;
        if d <= tolerance {
            *worst = worst.max(d);
            return Ok(());
        }
        if depth >= MAX_DEPTH {
            return Err(format!(
                "the move cannot be held within {tolerance} mm of its line: {d:.4} mm after {} pieces",
                1 << depth
            ));
        }
        let original = (self.interp)(&a.original, &b.original, 0.5);
        let target = Target {
            pose: original,
            tool: self.tool,
            configuration: None,
            seed: Some(a.corrected.nominal_q.clone()),
        };
        let corrected = correct_one(self.models, self.cal, self.nom, &target, Some(&a.corrected.nominal_q), self.starts)
            .map_err(|e| format!("a point added on the move: {e}"))?;
        let mid = PathPoint {
            original,
            corrected,
            fraction: 0.5 * (a.fraction + b.fraction),
        };
        self.split_into(a, &mid, tolerance, depth + 1, out, worst)?;
        out.push(mid.clone());
        self.split_into(&mid, b, tolerance, depth + 1, out, worst)
    }
}

/// A straight move in position with the rotation turned at a constant rate (a robot
/// controller's linear move).
pub fn slerp(a: &Pose, b: &Pose, s: f64) -> Pose {
    Pose::from_parts(
        nalgebra::Translation3::from(a.translation.vector.lerp(&b.translation.vector, s)),
        a.rotation.slerp(&b.rotation, s),
    )
}
