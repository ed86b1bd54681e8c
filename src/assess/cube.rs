//! The ISO 9283 test poses in a model's workspace ([`iso9283_commands`]): the largest cube with
//! edges along the base axes in which every point is reachable at the test orientation, P1–P5
//! placed in it ([`super::test_positions`]), and the commands that reach them.
//!
//! How the cube is found, for any mechanism (only its forward and inverse kinematics are used):
//! 1. `samples` configurations are drawn ([`crate::simulate::random_configurations`], seeded);
//!    their tool positions bound the region searched (unless a region is given), and the one
//!    nearest the middle of the input ranges gives the test orientation (unless one is given).
//! 2. A grid of equal spacing (`grid` points along the region's longest edge) is laid over the
//!    region; each point is solved at the test orientation ([`crate::compensate::compensate`]:
//!    inverse kinematics within the input limits, from the nearest sampled configuration).
//! 3. The largest cube of reachable grid points (a dynamic programme over the grid; between
//!    cubes of one size, the one nearest the region's centre) is then grown about its centre by
//!    bisection, up to one grid step each way and within the region, as long as its 27 corner,
//!    edge, face and centre points and P2–P5 are all reachable.
//!
//! A machine that commands its height and tool axis only ([`crate::model::Task::HeightAndAxis`],
//! a tilting head: x and y follow from its constraints) has no cube of commanded positions; it is
//! refused with what to do instead (test poses written by hand as a targets file).
//!
//! The commands are the model's inverse kinematics at P1–P5. For a calibrated model those are
//! compensated commands; with the nominal model, `kinecal compensate` on the written test poses
//! gives them (its input columns seed the calibrated inverse on the same branch).
use super::{test_positions, TestPose};
use crate::compensate::compensate;
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use nalgebra::{UnitQuaternion, Vector3};
use rand::SeedableRng;
use thiserror::Error;

/// Where the cube is searched and at which tool orientation; `None` takes the model's own (see
/// the [module docs](self)).
#[derive(Debug, Clone, PartialEq)]
pub struct CubeRequest {
    /// The box searched, `(min, max)` (mm); `None`: the sampled tool positions' bounding box.
    pub region: Option<(Vector3<f64>, Vector3<f64>)>,
    /// The test poses' tool orientation in the model's frame; `None`: the tool's at the sampled
    /// configuration nearest the middle of the input ranges.
    pub rotation: Option<UnitQuaternion<f64>>,
    /// Grid points along the region's longest edge (at least 3).
    pub grid: usize,
    /// Configurations sampled (at least 1).
    pub samples: usize,
    /// Seed of the sample.
    pub seed: u64,
}

impl Default for CubeRequest {
    fn default() -> Self {
        CubeRequest {
            region: None,
            rotation: None,
            grid: 10,
            samples: 500,
            seed: 1,
        }
    }
}

/// The test poses placed, and their commands.
#[derive(Debug, Clone, PartialEq)]
pub struct Iso9283Plan {
    /// P1–P5 (ids 1–5): positions (mm) and rotations `a, b, c` (degrees), as `kinecal assess
    /// --commanded` reads them.
    pub poses: Vec<TestPose>,
    /// The same as tool poses.
    pub targets: Vec<Pose>,
    /// The inputs that reach them (rad / mm), in the model's input order.
    pub commands: Vec<Vec<f64>>,
    /// The cube's low corner C1 (mm).
    pub cube_min: Vector3<f64>,
    /// The cube's side (mm).
    pub side: f64,
    /// The region searched, `(min, max)` (mm).
    pub region: (Vector3<f64>, Vector3<f64>),
    /// Grid points reachable and grid points tried.
    pub reachable: (usize, usize),
}

/// Why no test poses could be placed.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PlacementError {
    /// A request that cannot be met as stated.
    #[error("{0}")]
    Invalid(String),
    /// No sampled configuration assembled.
    #[error("none of the {0} sampled configurations assembles (forward kinematics failed at each)")]
    NoConfiguration(usize),
    /// Fewer than two neighbouring grid points reachable at the test orientation.
    #[error("no cube: {reachable} of {tried} grid points are reachable at the test orientation, no two of them neighbours; give a region (--x-mm, --y-mm, --z-mm) or an orientation the machine reaches")]
    NoCube {
        /// Points reachable.
        reachable: usize,
        /// Points tried.
        tried: usize,
    },
    /// A test pose the inverse kinematics does not reach (with the reason).
    #[error("P{pose} at ({x:.3}, {y:.3}, {z:.3}) mm is not reachable: {why}")]
    Unreachable {
        /// Test-pose id.
        pose: i64,
        /// Position (mm).
        x: f64,
        /// Position (mm).
        y: f64,
        /// Position (mm).
        z: f64,
        /// The inverse kinematics' reason.
        why: String,
    },
}

/// Solves positions at one orientation, each from the nearest sampled configuration.
struct Solver<'a> {
    model: &'a dyn Mechanism,
    inputs: &'a [InputSpec],
    rotation: UnitQuaternion<f64>,
    sampled: Vec<(Vec<f64>, Vector3<f64>)>,
}

impl Solver<'_> {
    fn nearest(&self, p: &Vector3<f64>) -> Vec<f64> {
        let d = |s: &(Vec<f64>, Vector3<f64>)| (s.1 - p).norm_squared();
        self.sampled
            .iter()
            .min_by(|a, b| d(a).total_cmp(&d(b)))
            .map_or_else(Vec::new, |s| s.0.clone())
    }

    fn pose(&self, p: &Vector3<f64>) -> Pose {
        Pose::from_parts((*p).into(), self.rotation)
    }

    /// The commands at `points`, or the index and reason of the first one not reached: the first
    /// from the nearest sampled configuration, the others from its solution (one branch: elbow,
    /// wrist, for all the points).
    fn solve(&self, points: &[Vector3<f64>]) -> Result<Vec<Vec<f64>>, (usize, String)> {
        let targets: Vec<Pose> = points.iter().map(|p| self.pose(p)).collect();
        let fail = |k: usize| move |e: crate::compensate::CompensationError| (e.target + k, e.source.to_string());
        let first = compensate(self.model, self.inputs, &targets[..1], Some(&[self.nearest(&points[0])]), &|_| {}).map_err(fail(0))?;
        let seeds = vec![first[0].clone(); points.len() - 1];
        let rest = compensate(self.model, self.inputs, &targets[1..], Some(&seeds), &|_| {}).map_err(fail(1))?;
        Ok(first.into_iter().chain(rest).collect())
    }

    fn reaches(&self, points: &[Vector3<f64>]) -> bool {
        self.solve(points).is_ok()
    }
}

/// The 27 corner, edge, face and centre points of the cube of side `side` about `c`, and P2–P5.
fn checkpoints(c: &Vector3<f64>, side: f64) -> Vec<Vector3<f64>> {
    let h = side / 2.0;
    let mut out = Vec::with_capacity(31);
    for i in -1..=1 {
        for j in -1..=1 {
            for k in -1..=1 {
                out.push(c + Vector3::new(i as f64, j as f64, k as f64) * h);
            }
        }
    }
    let (p, _) = test_positions(&(c - Vector3::repeat(h)), &(c + Vector3::repeat(h)));
    out.extend_from_slice(&p[1..]);
    out
}

/// The largest cube of `true` points of a grid (`n` points per axis, index `i + n0·(j + n1·k)`):
/// its number of points per edge (≥ 1) and low corner index, nearest `centre` (grid coordinates)
/// between equals; `None` when no point is reachable.
fn largest_cube(ok: &[bool], n: [usize; 3], centre: [f64; 3]) -> Option<(usize, [usize; 3])> {
    let at = |i: usize, j: usize, k: usize| i + n[0] * (j + n[1] * k);
    let mut s = vec![0usize; ok.len()];
    let mut best: Option<(usize, f64, [usize; 3])> = None;
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                if !ok[at(i, j, k)] {
                    continue;
                }
                let v = if i == 0 || j == 0 || k == 0 {
                    1
                } else {
                    let around = [
                        at(i - 1, j, k),
                        at(i, j - 1, k),
                        at(i, j, k - 1),
                        at(i - 1, j - 1, k),
                        at(i - 1, j, k - 1),
                        at(i, j - 1, k - 1),
                        at(i - 1, j - 1, k - 1),
                    ];
                    1 + around.iter().map(|&x| s[x]).min().unwrap_or(0)
                };
                s[at(i, j, k)] = v;
                // The cube of v points per edge ending at (i, j, k): its centre's distance.
                let half = (v - 1) as f64 / 2.0;
                let d =
                    (i as f64 - half - centre[0]).powi(2) + (j as f64 - half - centre[1]).powi(2) + (k as f64 - half - centre[2]).powi(2);
                if best.is_none_or(|(bv, bd, _)| v > bv || (v == bv && d < bd - 1e-12)) {
                    best = Some((v, d, [i + 1 - v, j + 1 - v, k + 1 - v]));
                }
            }
        }
    }
    best.map(|(v, _, low)| (v, low))
}

/// The ISO 9283 test poses in `model`'s workspace and their commands (see the
/// [module docs](self)): P1 at the centre of the largest reachable cube, P2–P5 on the diagonals
/// of its test plane at a tenth of the diagonal from the corners; every one solved by the
/// model's inverse kinematics within the input limits.
pub fn iso9283_commands(model: &dyn Mechanism, inputs: &[InputSpec], request: &CubeRequest) -> Result<Iso9283Plan, PlacementError> {
    if request.grid < 3 || request.samples == 0 {
        return Err(PlacementError::Invalid(format!(
            "the grid needs at least 3 points per edge (got {}) and at least one sampled configuration (got {})",
            request.grid, request.samples
        )));
    }
    if model.task() == crate::model::Task::HeightAndAxis {
        return Err(PlacementError::Invalid(
            "the machine commands its height and tool axis only (x and y follow from its constraints), so its positions fill no cube: \
             write the test poses as a targets file (id,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg), then `kinecal compensate` and `kinecal assess --commanded` take it"
                .into(),
        ));
    }
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(request.seed);
    let qs = crate::simulate::random_configurations(model, inputs, request.samples, &mut rng)
        .map_err(|e| PlacementError::Invalid(format!("sampling configurations: {e}")))?;
    let sampled: Vec<(Vec<f64>, Pose)> = qs.into_iter().filter_map(|q| model.forward(&q).ok().map(|t| (q, t))).collect();
    if sampled.is_empty() {
        return Err(PlacementError::NoConfiguration(request.samples));
    }
    let rotation = request.rotation.unwrap_or_else(|| {
        let middle: Vec<(f64, f64)> = inputs.iter().map(crate::simulate::input_range).collect();
        let off = |q: &[f64]| -> f64 {
            q.iter()
                .zip(&middle)
                .map(|(v, (lo, hi))| ((v - (lo + hi) / 2.0) / (hi - lo).max(1e-9)).powi(2))
                .sum()
        };
        let mid: Vec<f64> = middle.iter().map(|(lo, hi)| (lo + hi) / 2.0).collect();
        model.forward(&mid).map(|t| t.rotation).unwrap_or_else(|_| {
            let nearest = sampled.iter().min_by(|a, b| off(&a.0).total_cmp(&off(&b.0)));
            nearest.map_or(UnitQuaternion::identity(), |s| s.1.rotation)
        })
    });
    let region = request.region.unwrap_or_else(|| {
        let first = sampled[0].1.translation.vector;
        sampled.iter().fold((first, first), |(lo, hi), (_, t)| {
            (lo.inf(&t.translation.vector), hi.sup(&t.translation.vector))
        })
    });
    let (min, max) = region;
    if !(min.iter().chain(max.iter()).all(|v| v.is_finite()) && (max - min).min() > 0.0) {
        return Err(PlacementError::Invalid(format!(
            "the region must have a positive extent along x, y and z, got {:?} to {:?} mm",
            min.as_slice(),
            max.as_slice()
        )));
    }
    let solver = Solver {
        model,
        inputs,
        rotation,
        sampled: sampled.into_iter().map(|(q, t)| (q, t.translation.vector)).collect(),
    };
    // The grid: equal spacing, centred in the region.
    let extent = max - min;
    let step = extent.max() / (request.grid - 1) as f64;
    let n = [0, 1, 2].map(|k| (extent[k] / step + 1e-9).floor() as usize + 1);
    let origin = Vector3::from_fn(|k, _| min[k] + (extent[k] - (n[k] - 1) as f64 * step) / 2.0);
    let point = |i: usize, j: usize, k: usize| origin + Vector3::new(i as f64, j as f64, k as f64) * step;
    let mut ok = Vec::with_capacity(n[0] * n[1] * n[2]);
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                ok.push(solver.reaches(&[point(i, j, k)]));
            }
        }
    }
    let reachable = ok.iter().filter(|&&r| r).count();
    let centre = [0, 1, 2].map(|k| (n[k] - 1) as f64 / 2.0);
    let no_cube = PlacementError::NoCube {
        reachable,
        tried: ok.len(),
    };
    let (v, low) = largest_cube(&ok, n, centre).filter(|(v, _)| *v >= 2).ok_or(no_cube)?;
    let side0 = (v - 1) as f64 * step;
    let c = point(low[0], low[1], low[2]) + Vector3::repeat(side0 / 2.0);
    // Grow about the centre while every check point is reached, within the region.
    let room = 2.0 * (0..3).map(|k| (c[k] - min[k]).min(max[k] - c[k])).fold(f64::INFINITY, f64::min);
    let (mut lo, mut hi) = (side0, (side0 + 2.0 * step).min(room));
    for _ in 0..10 {
        if solver.reaches(&checkpoints(&c, lo)) {
            break;
        }
        (lo, hi) = (lo * 0.9, lo);
    }
    if solver.reaches(&checkpoints(&c, hi)) {
        lo = hi;
    }
    for _ in 0..8 {
        let mid = (lo + hi) / 2.0;
        if hi - lo < 1e-3 * step {
            break;
        }
        if solver.reaches(&checkpoints(&c, mid)) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let half = Vector3::repeat(lo / 2.0);
    let (positions, side) = test_positions(&(c - half), &(c + half));
    let commands = solver.solve(&positions).map_err(|(k, why)| PlacementError::Unreachable {
        pose: k as i64 + 1,
        x: positions[k].x,
        y: positions[k].y,
        z: positions[k].z,
        why,
    })?;
    let angles = se3::rpy(&rotation).map(f64::to_degrees);
    let poses = (1..)
        .zip(&positions)
        .map(|(pose, p)| TestPose {
            pose,
            position: *p,
            angles: Some(angles),
        })
        .collect();
    Ok(Iso9283Plan {
        poses,
        targets: positions.iter().map(|p| solver.pose(p)).collect(),
        commands,
        cube_min: c - half,
        side,
        region,
        reachable: (reachable, ok.len()),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_largest_cube_of_a_grid_is_found() {
        // 4 × 4 × 4 grid, all reachable but the corner (3, 3, 3): the largest cube has 3 points
        // per edge; of the eight such cubes the one nearest the centre (1.5, 1.5, 1.5)… all but
        // the one touching (3, 3, 3) tie; the first of them nearest the centre is taken.
        let n = [4, 4, 4];
        let mut ok = vec![true; 64];
        ok[63] = false;
        let (v, low) = largest_cube(&ok, n, [1.5; 3]).unwrap();
        assert_eq!(v, 3);
        assert!(low.iter().all(|&l| l <= 1) && low != [1, 1, 1], "{low:?}");
        ok = vec![true; 64];
        assert_eq!(largest_cube(&ok, n, [1.5; 3]), Some((4, [0, 0, 0])));
        assert_eq!(largest_cube(&[false; 64], n, [1.5; 3]), None);
    }

    #[test]
    fn checkpoints_hold_the_corners_and_the_test_positions() {
        let c = Vector3::new(1.0, 2.0, 3.0);
        let p = checkpoints(&c, 2.0);
        assert_eq!(p.len(), 31);
        assert!(p.contains(&Vector3::new(0.0, 1.0, 2.0)) && p.contains(&Vector3::new(2.0, 3.0, 4.0)) && p.contains(&c));
    }
}
