//! Why the data see some directions too weakly, where the cause is a known one.
//!
//! The commonest: a tool point (a ball, a probe tip, a reflector) on or near the last joint's
//! axis. Turning about that axis then barely moves the point, so a tilt of the axis moves it as
//! a shift of the link does, and the data cannot tell the two apart. Found from the model
//! alone, for any mechanism: the last input turned by a small angle at a configuration; where
//! the tool turns by that angle (a revolute last joint), the point's displacement over the
//! angle is its distance from the axis.
use crate::model::Mechanism;

/// Below this distance (mm) of the tool point from the last joint's axis, that is named as the
/// likely cause of directions held as seen too weakly.
pub const NEAR_AXIS_MM: f64 = 2.0;

/// The distance (mm) of the tool point of `m` from the axis of its last input at `q`, when that
/// input turns the tool (a revolute joint); `None` for a sliding last input or a pose the
/// model cannot evaluate.
pub fn tool_point_from_last_axis(m: &dyn Mechanism, q: &[f64]) -> Option<f64> {
    let k = q.len().checked_sub(1)?;
    let h = 1e-6;
    let at = |d: f64| {
        let mut qd = q.to_vec();
        qd[k] += d;
        m.forward(&qd).ok()
    };
    let (a, b) = (at(-h)?, at(h)?);
    let turn = (a.rotation.inverse() * b.rotation).angle();
    // A revolute last joint turns the tool by the input's change (a prismatic one does not).
    if (turn - 2.0 * h).abs() > 1e-3 * 2.0 * h {
        return None;
    }
    Some((b.translation.vector - a.translation.vector).norm() / turn)
}

/// The one-line cause of directions held as seen too weakly, when the tool point of `m` at `q`
/// is within [`NEAR_AXIS_MM`] of its last joint's axis, with what would reveal them; `None`
/// where no known cause applies.
pub fn known_cause(m: &dyn Mechanism, q: &[f64]) -> Option<String> {
    let d = tool_point_from_last_axis(m, q)?;
    let joint = m.input_names().last().cloned().unwrap_or_else(|| "last joint".into());
    (d < NEAR_AXIS_MM).then(|| {
        format!(
            "the tool point is {d:.2} mm from {joint}'s axis: a tilt of that axis moves it as a shift does; a tool point a few millimetres off the axis, or another instrument (a tracker's orientations, a probe), would show them"
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::framed::Framed;
    use crate::se3::{self, Pose};
    use nalgebra::Vector3;

    #[test]
    fn the_tool_points_distance_from_the_last_axis_is_found_and_named_when_near() {
        let q = [0.1, -0.3, 0.4, 0.2, 0.5, 0.3];
        for off in [0.0, 0.7, 25.0] {
            let arm = crate::io::builtin::model_file("irb120").unwrap().build();
            let tool = se3::pose_from_parts(Vector3::new(30.0, off, 0.0), Vector3::zeros());
            let m = Framed::new(arm, Pose::identity(), tool);
            let d = tool_point_from_last_axis(&m, &q).unwrap();
            assert!((d - off).abs() < 1e-5, "{off} mm off: found {d} mm");
            assert_eq!(known_cause(&m, &q).is_some(), off < NEAR_AXIS_MM, "{off} mm off");
        }
        let arm = crate::io::builtin::model_file("irb120").unwrap().build();
        let cause = known_cause(&*arm, &q).unwrap();
        assert!(cause.starts_with("the tool point is 0.00 mm from"), "{cause}");
    }
}
