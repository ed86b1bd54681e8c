//! Accuracy as the standards state it: ISO 9283 pose and distance characteristics; the test poses
//! in a model's workspace ([`cube`]); ISO 230-4 circular tests ([`circle`]).
//!
//! A robot is accepted on the figures of ISO 9283, not on an RMS: at a few **test poses** (P1–P5
//! in a cube of the workspace) the robot is commanded `n` times (**cycles**) and the attained
//! poses are measured. With `x̄, ȳ, z̄` the barycentre of the attained positions of one test pose
//! and `x_c, y_c, z_c` the commanded position (ISO 9283 §7.2.1, §7.2.2):
//!
//! ```text
//! AP_x = x̄ − x_c    AP_y = ȳ − y_c    AP_z = z̄ − z_c    AP_P = √(AP_x² + AP_y² + AP_z²)
//! AP_a = ā − a_c    AP_b = b̄ − b_c    AP_c = c̄ − c_c         (orientation accuracy)
//! l_j  = √((x_j − x̄)² + (y_j − ȳ)² + (z_j − z̄)²)   l̄ = mean l_j
//! S_l  = √(Σ (l_j − l̄)² / (n − 1))                  RP_l = l̄ + 3·S_l   (position repeatability)
//! RP_a = ±3·S_a,  S_a = √(Σ (a_j − ā)² / (n − 1))   (likewise b, c)    (orientation repeatability)
//! ```
//!
//! Distance accuracy and repeatability between two test poses 1 and 2 (§7.3), with
//! `D_j = |P_1j − P_2j|` attained in cycle `j` and `D_c = |P_c1 − P_c2|` commanded:
//!
//! ```text
//! AD_P = D̄ − D_c    AD_x = D̄_x − D_cx  (D_xj = |x_1j − x_2j|, D_cx = |x_c1 − x_c2|; y, z alike)
//! RD_P = ±3·S_D,    S_D = √(Σ (D_j − D̄)² / (n − 1))
//! AD_a = D̄_a − D_ca  (D_aj = a_1j − a_2j, D_ca = a_c1 − a_c2; b, c alike)
//! RD_a = ±3·S_Da,   S_Da = √(Σ (D_aj − D̄_a)² / (n − 1))                   (likewise b, c)
//! ```
//!
//! Units: mm and degrees. `a, b, c` are the rotations about x, y, z of the data files'
//! `roll_deg, pitch_deg, yaw_deg` (`R = Rz(c)·Ry(b)·Rx(a)`). The orientation figures do not
//! subtract angles: each attained orientation is taken against the commanded one as the rotation
//! vector `e_j = log(R_j·R_cᵀ)` (degrees), whose components are about the **base** axes x, y, z.
//! `AP_a, AP_b, AP_c` are the components of the mean `ē`, `RP_a,b,c` three sample standard
//! deviations of each component, and the distance figures use `e_1j − e_2j` for
//! `D_aj − D_ca`. These are the standard's angle differences only near a zero orientation: at
//! `(a, b, c) = (180°, 0, 180°)` the component about x is opposite in sign to `ā − a_c`, and at
//! a yaw of 90° the components about x and y exchange the roles of a and b. They are free of the
//! angles' singularities (a tool pointing down sits at a pitch of ±90°, where a and c alone swing
//! by degrees for a rotation of micro-radians) and of the ±180° seam.
pub mod circle;
pub mod cube;

pub use circle::{iso230_4, iso230_4_both, BidirectionalTest, CircleError, CircularTest, Plane};
pub use cube::{iso9283_commands, CubeRequest, Iso9283Plan, PlacementError};
use nalgebra::Vector3;
use serde::Serialize;
use std::collections::BTreeMap;
use thiserror::Error;

/// A commanded test pose: its id (1 for P1, …), position (mm) and, when the orientation is
/// assessed too, its rotations `a, b, c` (degrees).
#[derive(Debug, Clone, PartialEq)]
pub struct TestPose {
    /// Test-pose id.
    pub pose: i64,
    /// Commanded position (mm).
    pub position: Vector3<f64>,
    /// Commanded rotations about x, y, z (degrees), if the orientation is assessed.
    pub angles: Option<[f64; 3]>,
}

/// One attained pose: which test pose, which cycle, where the robot went.
#[derive(Debug, Clone, PartialEq)]
pub struct Attained {
    /// Test-pose id (as in [`TestPose::pose`]).
    pub pose: i64,
    /// Cycle number.
    pub cycle: i64,
    /// Attained position (mm).
    pub position: Vector3<f64>,
    /// Attained rotations about x, y, z (degrees), when measured.
    pub angles: Option<[f64; 3]>,
    /// 1-based line of the data file it came from (0 when not from a file), for messages.
    pub line: usize,
}

/// A mistake in the test data that makes the standard's figures impossible.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum AssessError {
    /// No attained pose at all.
    #[error("no attained poses")]
    Empty,
    /// An attained pose names a test pose that was not commanded.
    #[error("line {line}: test pose {pose} is not among the commanded poses ({known})")]
    UnknownPose {
        /// Its id.
        pose: i64,
        /// Its line.
        line: usize,
        /// The commanded ids.
        known: String,
    },
    /// A commanded test pose that no attained pose names.
    #[error("test pose {pose} was commanded but never attained: the attained file has no row with pose {pose}")]
    NotAttained {
        /// Its id.
        pose: i64,
    },
    /// A commanded test pose was measured fewer than twice (repeatability needs n ≥ 2).
    #[error("test pose {pose} has {cycles} attained pose(s): ISO 9283 needs at least 2 cycles per test pose (30 in the standard)")]
    TooFewCycles {
        /// Its id.
        pose: i64,
        /// How many.
        cycles: usize,
    },
    /// A test pose commanded twice.
    #[error("test pose {pose} is commanded twice")]
    DuplicateCommand {
        /// Its id.
        pose: i64,
    },
    /// A distance between test poses that were not both assessed, or that share no cycle.
    #[error("distance {from}–{to}: {why}")]
    Distance {
        /// First test pose.
        from: i64,
        /// Second test pose.
        to: i64,
        /// What is missing.
        why: String,
    },
}

/// ISO 9283 pose accuracy and repeatability at one test pose (mm, degrees).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PoseCharacteristics {
    /// Test-pose id.
    pub pose: i64,
    /// Number of cycles `n`.
    pub cycles: usize,
    /// `AP_x, AP_y, AP_z` (mm).
    pub ap_xyz: [f64; 3],
    /// `AP_P` (mm).
    pub ap_p: f64,
    /// `AP_a, AP_b, AP_c` (degrees), when orientations were measured and commanded.
    pub ap_abc: Option<[f64; 3]>,
    /// `l̄` (mm).
    pub l_mean: f64,
    /// `S_l` (mm).
    pub s_l: f64,
    /// `RP_l = l̄ + 3·S_l` (mm).
    pub rp_l: f64,
    /// `RP_a, RP_b, RP_c = ±3·S` (degrees).
    pub rp_abc: Option<[f64; 3]>,
}

/// ISO 9283 distance accuracy and repeatability between two test poses (mm).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DistanceCharacteristics {
    /// First test pose.
    pub from: i64,
    /// Second test pose.
    pub to: i64,
    /// Cycles in which both were attained.
    pub cycles: usize,
    /// Commanded distance `D_c` (mm).
    pub commanded_mm: f64,
    /// `AD_P = D̄ − D_c` (mm).
    pub ad_p: f64,
    /// `AD_x, AD_y, AD_z` (mm).
    pub ad_xyz: [f64; 3],
    /// `RD_P = ±3·S_D` (mm).
    pub rd_p: f64,
    /// `AD_a, AD_b, AD_c` (degrees), when orientations were measured and commanded at both.
    pub ad_abc: Option<[f64; 3]>,
    /// `RD_a, RD_b, RD_c = ±3·S_Da …` (degrees), likewise.
    pub rd_abc: Option<[f64; 3]>,
}

/// The standard's figures of one test run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Iso9283 {
    /// Pose accuracy and repeatability per test pose, in id order.
    pub poses: Vec<PoseCharacteristics>,
    /// Distance accuracy and repeatability for each pair asked for.
    pub distances: Vec<DistanceCharacteristics>,
}

/// The ISO 9283 test positions P1–P5 in the largest cube, edges along the base axes, centred in
/// the box `[min, max]` (mm): P1 at the cube's centre, P2–P5 on the diagonals of its test plane
/// C1–C2–C7–C8 (the vertical plane through the cube's xy diagonal), each at a tenth of the
/// diagonal's length from its corner: P2 near C1 (the low corner), P3 near C2, P4 near C7 (the
/// high corner), P5 near C8. Returns the positions and the cube's side.
pub fn test_positions(min: &Vector3<f64>, max: &Vector3<f64>) -> ([Vector3<f64>; 5], f64) {
    let side = (max - min).min();
    let centre = (min + max) / 2.0;
    let h = side / 2.0;
    let c1 = centre + Vector3::new(-h, -h, -h);
    let c2 = centre + Vector3::new(h, h, -h);
    let c7 = centre + Vector3::new(h, h, h);
    let c8 = centre + Vector3::new(-h, -h, h);
    let near = |from: Vector3<f64>, to: Vector3<f64>| from + (to - from) * 0.1;
    ([centre, near(c1, c7), near(c2, c8), near(c7, c1), near(c8, c2)], side)
}

/// How a virtual robot repeats: each attained pose is off the true machine's pose by a Gaussian
/// displacement of `position_mm` per axis and a Gaussian rotation of `orientation_rad` per axis.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Repeatability {
    /// Standard deviation per axis (mm).
    pub position_mm: f64,
    /// Standard deviation per axis (rad).
    pub orientation_rad: f64,
}

/// A test run on a (virtual) machine: `cycles` times through `commands` (test-pose id and the
/// inputs commanded there, rad / mm), each pose `truth` reaches off by `repeat`, then measured
/// with the tracker noise `noise` (position and orientation). Returns the attained poses in
/// cycle order, ready for [`iso9283`].
pub fn measure_cycles<M: crate::Mechanism + ?Sized, R: rand::Rng>(
    truth: &M,
    commands: &[(i64, Vec<f64>)],
    cycles: usize,
    repeat: &Repeatability,
    noise: &crate::measure::Noise,
    rng: &mut R,
) -> Result<Vec<Attained>, crate::error::CalibError> {
    use rand_distr::{Distribution, Normal};
    let normal = |s: f64| Normal::new(0.0, s).map_err(|e| crate::error::CalibError::InvalidOption(format!("σ {s}: {e}")));
    let (dp, dr) = (normal(repeat.position_mm)?, normal(repeat.orientation_rad)?);
    let (np, nr) = (normal(noise.position)?, normal(noise.orientation)?);
    let poses = commands
        .iter()
        .enumerate()
        .map(|(k, (_, q))| {
            truth
                .forward(q)
                .map_err(|source| crate::error::CalibError::Kinematics { pose: k, source })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut out = Vec::with_capacity(cycles * commands.len());
    for cycle in 0..cycles {
        for ((id, _), t) in commands.iter().zip(&poses) {
            let mut draw = |d: &Normal<f64>| Vector3::new(d.sample(rng), d.sample(rng), d.sample(rng));
            let turn = draw(&dr) + draw(&nr);
            let position = t.translation.vector + draw(&dp) + draw(&np);
            let rotation = crate::se3::so3_exp(&turn) * t.rotation;
            out.push(Attained {
                pose: *id,
                cycle: cycle as i64 + 1,
                position,
                angles: Some(crate::se3::rpy(&rotation).map(f64::to_degrees)),
                line: 0,
            });
        }
    }
    Ok(out)
}

/// The rotation of angles `a, b, c` (degrees): `Rz(c)·Ry(b)·Rx(a)`.
fn rotation(abc: &[f64; 3]) -> nalgebra::UnitQuaternion<f64> {
    nalgebra::UnitQuaternion::from_euler_angles(abc[0].to_radians(), abc[1].to_radians(), abc[2].to_radians())
}

/// Sample standard deviation (n − 1) of deviations from a mean.
fn sample_sd(deviations: &[f64]) -> f64 {
    let n = deviations.len();
    (deviations.iter().map(|d| d * d).sum::<f64>() / (n - 1) as f64).sqrt()
}

/// The ISO 9283 figures of `attained` against `commanded`: pose accuracy and repeatability at
/// every commanded test pose, and distance accuracy and repeatability between each pair of
/// `distances` (matched by cycle). See the module docs for the formulas.
pub fn iso9283(commanded: &[TestPose], attained: &[Attained], distances: &[(i64, i64)]) -> Result<Iso9283, AssessError> {
    if attained.is_empty() {
        return Err(AssessError::Empty);
    }
    let mut by_id: BTreeMap<i64, &TestPose> = BTreeMap::new();
    for c in commanded {
        if by_id.insert(c.pose, c).is_some() {
            return Err(AssessError::DuplicateCommand { pose: c.pose });
        }
    }
    let mut groups: BTreeMap<i64, Vec<&Attained>> = by_id.keys().map(|&k| (k, Vec::new())).collect();
    for a in attained {
        match groups.get_mut(&a.pose) {
            Some(g) => g.push(a),
            None => {
                return Err(AssessError::UnknownPose {
                    pose: a.pose,
                    line: a.line,
                    known: by_id.keys().map(|k| k.to_string()).collect::<Vec<_>>().join(", "),
                })
            }
        }
    }
    let mut poses = Vec::new();
    for (&id, group) in &groups {
        if group.is_empty() {
            return Err(AssessError::NotAttained { pose: id });
        }
        if group.len() < 2 {
            return Err(AssessError::TooFewCycles {
                pose: id,
                cycles: group.len(),
            });
        }
        poses.push(pose_characteristics(by_id[&id], group));
    }
    let distances = distances
        .iter()
        .map(|&(from, to)| distance_characteristics(&by_id, &groups, from, to))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Iso9283 { poses, distances })
}

/// AP and RP at one test pose from its attained poses (at least two).
fn pose_characteristics(c: &TestPose, group: &[&Attained]) -> PoseCharacteristics {
    let n = group.len() as f64;
    let bary = group.iter().map(|a| a.position).sum::<Vector3<f64>>() / n;
    let ap = bary - c.position;
    let l: Vec<f64> = group.iter().map(|a| (a.position - bary).norm()).collect();
    let l_mean = l.iter().sum::<f64>() / n;
    let s_l = sample_sd(&l.iter().map(|v| v - l_mean).collect::<Vec<_>>());
    let angles: Option<Vec<[f64; 3]>> = group.iter().map(|a| a.angles).collect();
    let (ap_abc, rp_abc) = match (angles, c.angles) {
        (Some(angles), Some(commanded)) => {
            // Each attained orientation against the commanded one, as the small rotation about
            // the base axes x, y, z that takes one to the other: to first order the differences
            // of a, b, c, and free of the singularities of the angles themselves.
            let dev: Vec<Vector3<f64>> = angles.iter().map(|a| orientation_error(a, &commanded)).collect();
            let mean = dev.iter().sum::<Vector3<f64>>() / n;
            let mut rp = [0.0; 3];
            for (k, r) in rp.iter_mut().enumerate() {
                *r = 3.0 * sample_sd(&dev.iter().map(|d| d[k] - mean[k]).collect::<Vec<_>>());
            }
            (Some([mean.x, mean.y, mean.z]), Some(rp))
        }
        _ => (None, None),
    };
    PoseCharacteristics {
        pose: c.pose,
        cycles: group.len(),
        ap_xyz: [ap.x, ap.y, ap.z],
        ap_p: ap.norm(),
        ap_abc,
        l_mean,
        s_l,
        rp_l: l_mean + 3.0 * s_l,
        rp_abc,
    }
}

/// AD and RD between two test poses, over the cycles in which both were attained.
fn distance_characteristics(
    by_id: &BTreeMap<i64, &TestPose>,
    groups: &BTreeMap<i64, Vec<&Attained>>,
    from: i64,
    to: i64,
) -> Result<DistanceCharacteristics, AssessError> {
    let missing = |why: String| AssessError::Distance { from, to, why };
    let (Some(c1), Some(c2)) = (by_id.get(&from), by_id.get(&to)) else {
        return Err(missing("both must be commanded test poses".into()));
    };
    let second: BTreeMap<i64, &Attained> = groups[&to].iter().map(|a| (a.cycle, *a)).collect();
    let matched: Vec<(&Attained, &Attained)> = groups[&from]
        .iter()
        .filter_map(|a| second.get(&a.cycle).map(|b| (*a, *b)))
        .collect();
    let pairs: Vec<(Vector3<f64>, Vector3<f64>)> = matched.iter().map(|(a, b)| (a.position, b.position)).collect();
    if pairs.len() < 2 {
        return Err(missing(format!(
            "{} cycle(s) attained both (the cycle columns must match; at least 2 needed)",
            pairs.len()
        )));
    }
    let n = pairs.len() as f64;
    let d: Vec<f64> = pairs.iter().map(|(p, q)| (p - q).norm()).collect();
    let d_mean = d.iter().sum::<f64>() / n;
    let dc = c1.position - c2.position;
    let mut ad_xyz = [0.0; 3];
    for (k, ad) in ad_xyz.iter_mut().enumerate() {
        let mean = pairs.iter().map(|(p, q)| (p[k] - q[k]).abs()).sum::<f64>() / n;
        *ad = mean - dc[k].abs();
    }
    Ok(DistanceCharacteristics {
        from,
        to,
        cycles: pairs.len(),
        commanded_mm: dc.norm(),
        ad_p: d_mean - dc.norm(),
        ad_xyz,
        rd_p: 3.0 * sample_sd(&d.iter().map(|v| v - d_mean).collect::<Vec<_>>()),
        ad_abc: orientation_distance(c1, c2, &matched).map(|(ad, _)| ad),
        rd_abc: orientation_distance(c1, c2, &matched).map(|(_, rd)| rd),
    })
}

/// The orientation error `log(R·R_cᵀ)` (degrees, about the base axes) of attained angles.
fn orientation_error(attained: &[f64; 3], commanded: &[f64; 3]) -> Vector3<f64> {
    crate::se3::so3_log(&(rotation(attained) * rotation(commanded).inverse())).map(f64::to_degrees)
}

/// `AD_a,b,c` and `RD_a,b,c` (degrees) of matched cycles, when both test poses have commanded
/// and attained orientations: `D_aj − D_ca` is `e_1j − e_2j`, the difference of the two
/// orientation errors (module docs).
fn orientation_distance(c1: &TestPose, c2: &TestPose, matched: &[(&Attained, &Attained)]) -> Option<([f64; 3], [f64; 3])> {
    let (ca, cb) = (c1.angles?, c2.angles?);
    let d: Vec<Vector3<f64>> = matched
        .iter()
        .map(|(a, b)| Some(orientation_error(&a.angles?, &ca) - orientation_error(&b.angles?, &cb)))
        .collect::<Option<_>>()?;
    let n = d.len() as f64;
    let mean = d.iter().sum::<Vector3<f64>>() / n;
    let mut rd = [0.0; 3];
    for (k, r) in rd.iter_mut().enumerate() {
        *r = 3.0 * sample_sd(&d.iter().map(|v| v[k] - mean[k]).collect::<Vec<_>>());
    }
    Some(([mean.x, mean.y, mean.z], rd))
}

/// Attained poses no robot reaches that far from its commands: a mean position error beyond
/// this (mm) is a mistake in the files (another run's file, another frame, another unit), not an
/// accuracy.
pub const PLAUSIBLE_MM: f64 = 20.0;
/// The same for the mean orientation error (degrees).
pub const PLAUSIBLE_DEG: f64 = 5.0;

/// A line naming the worst test pose when the figures are beyond any plausible accuracy
/// ([`PLAUSIBLE_MM`], [`PLAUSIBLE_DEG`]): the files do not belong together (another run's
/// attained file, a frame not registered, metres for mm). `None` when they are plausible.
pub fn implausible(figures: &Iso9283) -> Option<String> {
    let worst = figures.poses.iter().max_by(|a, b| a.ap_p.total_cmp(&b.ap_p))?;
    if worst.ap_p > PLAUSIBLE_MM {
        return Some(format!(
            "test pose {} is attained {:.3} mm from where it was commanded (AP_P; {} pose(s) beyond {PLAUSIBLE_MM} mm): no robot is that far off, so the attained file is not of these commands (another run's file, another frame or unit?)",
            worst.pose,
            worst.ap_p,
            figures.poses.iter().filter(|p| p.ap_p > PLAUSIBLE_MM).count()
        ));
    }
    let turn = |p: &PoseCharacteristics| p.ap_abc.map_or(0.0, |a| Vector3::from(a).norm());
    let worst = figures.poses.iter().max_by(|a, b| turn(a).total_cmp(&turn(b)))?;
    (turn(worst) > PLAUSIBLE_DEG).then(|| {
        format!(
            "test pose {} is attained turned {:.3}° from its commanded orientation: beyond any plausible accuracy ({PLAUSIBLE_DEG}°), so the angles are not of these commands (another convention, radians in _deg columns?)",
            worst.pose,
            turn(worst)
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(pose: i64, cycle: i64, x: f64, y: f64, z: f64) -> Attained {
        Attained {
            pose,
            cycle,
            position: Vector3::new(x, y, z),
            angles: None,
            line: 0,
        }
    }

    fn commanded(pose: i64, x: f64, y: f64, z: f64) -> TestPose {
        TestPose {
            pose,
            position: Vector3::new(x, y, z),
            angles: None,
        }
    }

    /// A hand-worked example: P1 commanded at the origin, attained at (1, 0, 0), (1, 2, 0),
    /// (1, 0, 2). Barycentre (1, 2/3, 2/3): AP = (1, 2/3, 2/3), AP_P = √17 / 3. Distances to it
    /// l = √8/3, √20/3, √20/3; l̄ = (√8 + 2√20)/9; S_l from the (n − 1) formula.
    #[test]
    fn pose_accuracy_and_repeatability_by_hand() {
        let r = iso9283(
            &[commanded(1, 0.0, 0.0, 0.0)],
            &[at(1, 1, 1.0, 0.0, 0.0), at(1, 2, 1.0, 2.0, 0.0), at(1, 3, 1.0, 0.0, 2.0)],
            &[],
        )
        .unwrap();
        let p = &r.poses[0];
        let close = |a: f64, b: f64| (a - b).abs() < 1e-12;
        assert!(close(p.ap_xyz[0], 1.0) && close(p.ap_xyz[1], 2.0 / 3.0) && close(p.ap_xyz[2], 2.0 / 3.0));
        assert!(close(p.ap_p, 17f64.sqrt() / 3.0));
        let l = [8f64.sqrt() / 3.0, 20f64.sqrt() / 3.0, 20f64.sqrt() / 3.0];
        let l_mean = (l[0] + l[1] + l[2]) / 3.0;
        let s_l = (l.iter().map(|v| (v - l_mean).powi(2)).sum::<f64>() / 2.0).sqrt();
        assert!(close(p.l_mean, l_mean) && close(p.s_l, s_l) && close(p.rp_l, l_mean + 3.0 * s_l));
        // The numbers themselves: l̄ = 1.30808…, S_l = 0.31633…, RP_l = 2.25707…
        assert!((p.rp_l - 2.25707).abs() < 1e-5, "{}", p.rp_l);
    }

    /// Distance between P1 at the origin and P2 at (10, 0, 0), two cycles attained 10.1 and
    /// 9.9 mm apart (x only): D̄ = 10, AD_P = 0, S_D = √0.02, RD = 3√0.02.
    #[test]
    fn distance_accuracy_and_repeatability_by_hand() {
        let r = iso9283(
            &[commanded(1, 0.0, 0.0, 0.0), commanded(2, 10.0, 0.0, 0.0)],
            &[
                at(1, 1, 0.0, 0.0, 0.0),
                at(1, 2, 0.0, 0.0, 0.0),
                at(2, 1, 10.1, 0.0, 0.0),
                at(2, 2, 9.9, 0.0, 0.0),
            ],
            &[(1, 2)],
        )
        .unwrap();
        let d = &r.distances[0];
        assert_eq!(d.cycles, 2);
        assert!(d.ad_p.abs() < 1e-12 && d.ad_xyz[0].abs() < 1e-12);
        assert!((d.rd_p - 3.0 * 0.02f64.sqrt()).abs() < 1e-12, "{}", d.rd_p);
    }

    /// Orientation: rotations about x of 179° and −179° average to 180°, not 0; at a pitch of
    /// 90° (gimbal lock) a rotation of 0.01° about z reads as 0.01°.
    #[test]
    fn orientation_accuracy_across_the_180_degree_seam() {
        let mut a = at(1, 1, 0.0, 0.0, 0.0);
        a.angles = Some([179.0, 0.0, 0.0]);
        let mut b = at(1, 2, 0.0, 0.0, 0.0);
        b.angles = Some([-179.0, 0.0, 0.0]);
        let mut c = commanded(1, 0.0, 0.0, 0.0);
        c.angles = Some([180.0, 0.0, 0.0]);
        let r = iso9283(&[c], &[a, b], &[]).unwrap();
        let ap = r.poses[0].ap_abc.unwrap();
        let rp = r.poses[0].rp_abc.unwrap();
        assert!(ap.iter().all(|v| v.abs() < 1e-9), "{ap:?}");
        assert!((rp[0] - 3.0 * 2f64.sqrt()).abs() < 1e-9, "{rp:?}");
        // Pointing along −x (pitch 90°): attained 0.01° about the base z from the command.
        let command = nalgebra::UnitQuaternion::from_euler_angles(0.3, std::f64::consts::FRAC_PI_2, -0.2);
        let turned = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.01f64.to_radians()) * command;
        let deg = |q: &nalgebra::UnitQuaternion<f64>| crate::se3::rpy(q).map(f64::to_degrees);
        let mut c = commanded(1, 0.0, 0.0, 0.0);
        c.angles = Some(deg(&command));
        let attained: Vec<Attained> = (0..2)
            .map(|k| Attained {
                angles: Some(deg(&turned)),
                ..at(1, k, 0.0, 0.0, 0.0)
            })
            .collect();
        let ap = iso9283(&[c], &attained, &[]).unwrap().poses[0].ap_abc.unwrap();
        assert!(ap[0].abs() < 1e-9 && ap[1].abs() < 1e-9 && (ap[2] - 0.01).abs() < 1e-9, "{ap:?}");
    }

    /// A virtual robot with a systematic error (0.30, −0.20, 0.10) mm at P1 and a repeatability
    /// of σ = 10 µm per axis, 3000 cycles: AP is the systematic error, and RP_l the value a 3-D
    /// Gaussian gives (l follows a Maxwell law: l̄ = 2σ√(2/π), S_l = σ√(3 − 8/π)).
    #[test]
    fn a_simulated_robot_gives_its_systematic_error_and_repeatability() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9283);
        let sigma = 0.01;
        let noise = Normal::new(0.0, sigma).unwrap();
        let offset = Vector3::new(0.30, -0.20, 0.10);
        let c = commanded(1, 400.0, 0.0, 500.0);
        let attained: Vec<Attained> = (0..3000)
            .map(|k| {
                let e = Vector3::new(noise.sample(&mut rng), noise.sample(&mut rng), noise.sample(&mut rng));
                let p = c.position + offset + e;
                at(1, k, p.x, p.y, p.z)
            })
            .collect();
        let r = iso9283(&[c], &attained, &[]).unwrap();
        let p = &r.poses[0];
        for k in 0..3 {
            assert!((p.ap_xyz[k] - offset[k]).abs() < 1e-3, "{:?}", p.ap_xyz);
        }
        let pi = std::f64::consts::PI;
        let expected = sigma * (2.0 * (2.0 / pi).sqrt() + 3.0 * (3.0 - 8.0 / pi).sqrt());
        assert!((p.rp_l / expected - 1.0).abs() < 0.03, "RP_l {} against {expected}", p.rp_l);
    }

    #[test]
    fn test_positions_sit_a_tenth_of_the_diagonal_from_the_corners() {
        let (p, side) = test_positions(&Vector3::new(-50.0, -50.0, 350.0), &Vector3::new(50.0, 80.0, 450.0));
        assert_eq!(side, 100.0);
        assert_eq!(p[0], Vector3::new(0.0, 15.0, 400.0));
        let diagonal = 100.0 * 3f64.sqrt();
        let corners = [
            Vector3::new(-50.0, -35.0, 350.0),
            Vector3::new(50.0, 65.0, 350.0),
            Vector3::new(50.0, 65.0, 450.0),
            Vector3::new(-50.0, -35.0, 450.0),
        ];
        for (k, c) in corners.iter().enumerate() {
            assert!(((p[k + 1] - c).norm() - 0.1 * diagonal).abs() < 1e-9, "P{}", k + 2);
        }
        // P2 and P4 on one diagonal, symmetric about P1.
        assert!((p[1] + p[3] - 2.0 * p[0]).norm() < 1e-12);
    }

    /// By hand, orientation distance figures (§7.3): P1 commanded at (0, 0, 0)°, attained at
    /// yaw 1, 2, 3° in cycles 1–3; P2 commanded at yaw 90°, attained at yaw 90.5° in each cycle.
    /// Rotations about z alone: the errors are (0, 0, 1), (0, 0, 2), (0, 0, 3) and (0, 0, 0.5)
    /// exactly, so D_cj − D_cc = 0.5, 1.5, 2.5: AD_c = 1.5, S = 1, RD_c = 3; AD_a = AD_b = 0 and
    /// RD_a = RD_b = 0. Positions 100 mm apart as commanded: AD_P = RD_P = 0.
    #[test]
    fn orientation_distance_accuracy_and_repeatability_by_hand() {
        let with = |pose: i64, cycle: i64, x: f64, yaw: f64| Attained {
            angles: Some([0.0, 0.0, yaw]),
            ..at(pose, cycle, x, 0.0, 0.0)
        };
        let c = [
            TestPose {
                angles: Some([0.0; 3]),
                ..commanded(1, 0.0, 0.0, 0.0)
            },
            TestPose {
                angles: Some([0.0, 0.0, 90.0]),
                ..commanded(2, 100.0, 0.0, 0.0)
            },
        ];
        let a: Vec<Attained> = (1..=3).flat_map(|k| [with(1, k, 0.0, k as f64), with(2, k, 100.0, 90.5)]).collect();
        let r = iso9283(&c, &a, &[(1, 2)]).unwrap();
        let d = &r.distances[0];
        let (ad, rd) = (d.ad_abc.unwrap(), d.rd_abc.unwrap());
        let close = |a: f64, b: f64| (a - b).abs() < 1e-9;
        assert!(close(ad[0], 0.0) && close(ad[1], 0.0) && close(ad[2], 1.5), "{ad:?}");
        assert!(close(rd[0], 0.0) && close(rd[1], 0.0) && close(rd[2], 3.0), "{rd:?}");
        assert!(close(d.ad_p, 0.0) && close(d.rd_p, 0.0));
        // Pose figures: AP_c of P1 is the mean 2°, RP_c = 3·1; P2's AP_c 0.5°, RP_c 0.
        assert!(close(r.poses[0].ap_abc.unwrap()[2], 2.0) && close(r.poses[0].rp_abc.unwrap()[2], 3.0));
        assert!(close(r.poses[1].ap_abc.unwrap()[2], 0.5) && close(r.poses[1].rp_abc.unwrap()[2], 0.0));
        // Plausible; the same attained file 100 mm off is not, nor 10° off.
        assert_eq!(implausible(&r), None);
        let far: Vec<Attained> = a
            .iter()
            .map(|x| Attained {
                position: x.position + Vector3::new(0.0, 100.0, 0.0),
                ..x.clone()
            })
            .collect();
        let line = implausible(&iso9283(&c, &far, &[]).unwrap()).unwrap();
        assert!(line.contains("100.000 mm") && line.contains("2 pose(s) beyond 20 mm"), "{line}");
        let turned: Vec<Attained> = a
            .iter()
            .map(|x| with(x.pose, x.cycle, x.position.x, x.angles.unwrap()[2] + 10.0))
            .collect();
        let line = implausible(&iso9283(&c, &turned, &[]).unwrap()).unwrap();
        assert!(line.contains("test pose 1") && line.contains("turned 12.000°"), "{line}");
    }

    #[test]
    fn mistakes_are_named() {
        let c = [commanded(1, 0.0, 0.0, 0.0), commanded(2, 1.0, 0.0, 0.0)];
        let one = [at(1, 1, 0.0, 0.0, 0.0), at(1, 2, 0.0, 0.0, 0.0), at(2, 1, 1.0, 0.0, 0.0)];
        assert!(matches!(
            iso9283(&c, &one, &[]),
            Err(AssessError::TooFewCycles { pose: 2, cycles: 1 })
        ));
        let mut unknown = one.to_vec();
        unknown.push(Attained {
            line: 7,
            ..at(9, 1, 0.0, 0.0, 0.0)
        });
        let e = iso9283(&c, &unknown, &[]).unwrap_err();
        assert_eq!(e.to_string(), "line 7: test pose 9 is not among the commanded poses (1, 2)");
        assert!(matches!(iso9283(&c, &[], &[]), Err(AssessError::Empty)));
        let never = [at(1, 1, 0.0, 0.0, 0.0), at(1, 2, 0.0, 0.0, 0.0)];
        assert!(matches!(iso9283(&c, &never, &[]), Err(AssessError::NotAttained { pose: 2 })));
    }
}
