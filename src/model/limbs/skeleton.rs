//! The drawing of a [`LimbMechanism`] at home for the report's 3-D view
//! ([`crate::model::Mechanism::skeleton`]): each limb from where it starts through its joints'
//! origins to its end, the base's outline through the limbs' first joints and the platform's
//! outline through the limbs' ends on it.
use super::*;

impl LimbMechanism {
    /// Polylines of the limbs at their home joint values, the base's outline (a closed polygon
    /// through the first joints of the limbs on the base, when there are three or more), then
    /// the platform's outline (a closed polygon through the ends of the limbs that close on the
    /// platform, or spokes from the platform origin when fewer than three do), in the base
    /// frame (mm).
    pub(super) fn home_skeleton(&self) -> Vec<Vec<Vector3<f64>>> {
        let mut frames: Vec<Vec<Pose>> = Vec::with_capacity(self.limbs.len());
        let mut lines = Vec::with_capacity(self.limbs.len() + 1);
        let (mut ends, mut bases) = (Vec::new(), Vec::new());
        for l in &self.limbs {
            let start = match l.start {
                Some(b) => frames.get(b.limb).and_then(|f| f.get(b.joint)).copied().unwrap_or(Pose::identity()),
                None => Pose::identity(),
            };
            let own: Vec<Pose> = l.chain.frames(&l.home).unwrap_or_default().into_iter().map(|g| start * g).collect();
            // A limb on the base starts at its first joint (the base's outline joins those); a
            // branch starts at the body it is hinged on.
            let mut line = Vec::with_capacity(own.len() + 1);
            match l.start {
                Some(_) => line.push(start.translation.vector),
                None => bases.extend(own.first().map(|g| g.translation.vector)),
            }
            line.extend(own.iter().map(|g| g.translation.vector));
            if l.end_on.is_none() {
                if let Some(end) = own.last() {
                    ends.push(end.translation.vector);
                }
            }
            lines.push(line);
            frames.push(own);
        }
        if bases.len() >= 3 {
            bases.push(bases[0]);
            lines.push(bases);
        }
        let centre = self.home.translation.vector;
        if ends.len() >= 3 {
            let mut outline = ends.clone();
            outline.push(ends[0]);
            lines.push(outline);
        } else {
            for e in ends {
                lines.push(vec![centre, e]);
            }
        }
        lines
    }
}
