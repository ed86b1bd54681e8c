//! ISO 230-4 circular tests: a machine (or robot) commanded along a circle of nominal centre and
//! radius, its path measured by a ballbar (radius readings about the pivot at the nominal centre)
//! or by a tracker (points). With the measured points `p_i` in the circle's plane about the
//! nominal centre, and `c` the centre of the least-squares circle (minimising `Σ (|p_i − c| − r)²`):
//!
//! ```text
//! G     = max |p_i − c| − min |p_i − c|     circular deviation (ISO 230-4 §3.2, LSQ centre)
//! F_max = max (|p_i| − R),  F_min = min (|p_i| − R)   radial deviation about the nominal centre
//!                                                     (the ballbar's pivot), §3.3; R nominal
//! c                                                   the path's centre offset from the nominal
//! ```
//!
//! Run in both directions (clockwise and anticlockwise, [`iso230_4_both`]): `G` of each
//! direction, `G(b)` of both paths together about their common least-squares centre, and the
//! circular hysteresis `H`, the largest radial difference between the two paths at the same
//! angle (§3.4), each path's radius interpolated linearly between its measured angles.
//!
//! All in mm; angles of the points in degrees from the plane's first axis (x of the `xy` plane, y
//! of `yz`, z of `zx`) towards its second. A path of the right shape off-centre gives a G of
//! about zero and F of ± the offset; a path of the wrong shape (an ellipse from unequal axis
//! gains) gives a G of the shape's difference of radii.
use nalgebra::{Matrix3, Vector2, Vector3};
use serde::Serialize;
use thiserror::Error;

/// The plane of a circular test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum Plane {
    /// x–y: coordinates (x, y).
    Xy,
    /// y–z: coordinates (y, z).
    Yz,
    /// z–x: coordinates (z, x).
    Zx,
}

impl std::str::FromStr for Plane {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "xy" => Ok(Plane::Xy),
            "yz" => Ok(Plane::Yz),
            "zx" | "xz" => Ok(Plane::Zx),
            _ => Err(format!("plane '{s}': expected xy, yz or zx")),
        }
    }
}

impl Plane {
    /// The in-plane coordinates of a point (its first and second axis).
    pub fn coordinates(self, p: &Vector3<f64>) -> [f64; 2] {
        match self {
            Plane::Xy => [p.x, p.y],
            Plane::Yz => [p.y, p.z],
            Plane::Zx => [p.z, p.x],
        }
    }
}

/// A mistake that leaves the circle's figures undefined.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CircleError {
    /// Fewer than three points.
    #[error("a circle needs at least 3 measured points, got {0}")]
    TooFewPoints(usize),
    /// A nominal radius that is not positive.
    #[error("the nominal radius must be positive, got {0} mm")]
    Radius(f64),
    /// A point that is not a finite number, or points on one line (no circle through them).
    #[error("{0}")]
    Degenerate(String),
}

/// The ISO 230-4 figures of one measured circle (mm, degrees).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CircularTest {
    /// Number of measured points.
    pub points: usize,
    /// Nominal radius `R` (mm).
    pub nominal_radius_mm: f64,
    /// Centre of the least-squares circle from the nominal centre, in the plane (mm).
    pub centre_offset_mm: [f64; 2],
    /// Radius of the least-squares circle (mm).
    pub lsq_radius_mm: f64,
    /// Circular deviation `G`: max − min radius about the least-squares centre (mm).
    pub circular_deviation_g_mm: f64,
    /// Radial deviation `F_max` (mm), about the nominal centre.
    pub radial_deviation_f_max_mm: f64,
    /// Radial deviation `F_min` (mm), about the nominal centre.
    pub radial_deviation_f_min_mm: f64,
    /// Each point's angle about the nominal centre (degrees) and radial deviation `|p_i| − R`
    /// (mm), in the order measured: the polar plot's path.
    pub radial: Vec<[f64; 2]>,
}

/// Points from ballbar readings: the radius (mm) at each angle (degrees) about the pivot.
pub fn points_from_radii(readings: &[[f64; 2]]) -> Vec<[f64; 2]> {
    readings
        .iter()
        .map(|[a, r]| {
            let (s, c) = a.to_radians().sin_cos();
            [r * c, r * s]
        })
        .collect()
}

/// The least-squares circle (centre, radius) of points: the algebraic fit (linear in the centre
/// and `r² − |c|²`) refined by Gauss–Newton on the geometric distances `|p_i − c| − r`.
pub fn least_squares_circle(points: &[[f64; 2]]) -> Result<(Vector2<f64>, f64), CircleError> {
    if points.len() < 3 {
        return Err(CircleError::TooFewPoints(points.len()));
    }
    if points.iter().flatten().any(|v| !v.is_finite()) {
        return Err(CircleError::Degenerate("a measured point is not a finite number".into()));
    }
    let degenerate = || CircleError::Degenerate("the points lie on one line: no circle through them".into());
    // Algebraic fit: u² + v² + D·u + E·v + F = 0, centre (−D/2, −E/2).
    let (mut n, mut b) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
    for [u, v] in points {
        let row = Vector3::new(*u, *v, 1.0);
        n += row * row.transpose();
        b -= row * (u * u + v * v);
    }
    let def = n.lu().solve(&b).ok_or_else(degenerate)?;
    let mut c = Vector2::new(-def[0] / 2.0, -def[1] / 2.0);
    let mut r = (c.norm_squared() - def[2]).max(0.0).sqrt();
    if !(c.iter().all(|v| v.is_finite()) && r.is_finite() && r > 0.0) {
        return Err(degenerate());
    }
    for _ in 0..50 {
        let (mut jtj, mut jtr) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
        for [u, v] in points {
            let d = Vector2::new(u - c.x, v - c.y);
            let dist = d.norm().max(1e-300);
            let row = Vector3::new(-d.x / dist, -d.y / dist, -1.0);
            jtj += row * row.transpose();
            jtr += row * (dist - r);
        }
        let step = jtj.lu().solve(&(-jtr)).ok_or_else(degenerate)?;
        c += Vector2::new(step[0], step[1]);
        r += step[2];
        if step.norm() < 1e-13 * r.max(1.0) {
            break;
        }
    }
    Ok((c, r))
}

/// The ISO 230-4 figures of a circle measured at `points` (in-plane coordinates about the
/// nominal centre, mm) against the nominal radius `nominal_radius` (mm); see the module docs.
pub fn iso230_4(points: &[[f64; 2]], nominal_radius: f64) -> Result<CircularTest, CircleError> {
    if !(nominal_radius.is_finite() && nominal_radius > 0.0) {
        return Err(CircleError::Radius(nominal_radius));
    }
    let (c, r) = least_squares_circle(points)?;
    let about_lsq: Vec<f64> = points.iter().map(|[u, v]| (Vector2::new(*u, *v) - c).norm()).collect();
    let fold = |v: &[f64]| {
        v.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| (lo.min(*x), hi.max(*x)))
    };
    let (lo, hi) = fold(&about_lsq);
    let radial: Vec<[f64; 2]> = points
        .iter()
        .map(|[u, v]| [v.atan2(*u).to_degrees(), u.hypot(*v) - nominal_radius])
        .collect();
    let (f_min, f_max) = fold(&radial.iter().map(|p| p[1]).collect::<Vec<_>>());
    Ok(CircularTest {
        points: points.len(),
        nominal_radius_mm: nominal_radius,
        centre_offset_mm: [c.x, c.y],
        lsq_radius_mm: r,
        circular_deviation_g_mm: hi - lo,
        radial_deviation_f_max_mm: f_max,
        radial_deviation_f_min_mm: f_min,
        radial,
    })
}

/// The ISO 230-4 figures of a circle run in both directions (mm): each direction's own, the
/// bidirectional circular deviation `G(b)` (max − min radius of both paths about their common
/// least-squares centre) and the circular hysteresis `H` (the largest radial difference between
/// the two paths at the same angle, about that centre).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BidirectionalTest {
    /// The clockwise run alone.
    pub clockwise: CircularTest,
    /// The anticlockwise run alone.
    pub anticlockwise: CircularTest,
    /// Centre of the least-squares circle of both paths from the nominal centre (mm).
    pub centre_offset_mm: [f64; 2],
    /// `G(b)`: max − min radius of both paths about their common least-squares centre (mm).
    pub circular_deviation_g_both_mm: f64,
    /// `H`: the largest radial difference between the two paths at the same angle (mm).
    pub circular_hysteresis_h_mm: f64,
}

/// Each point's angle (rad, in [−π, π)) and radius about `c`, sorted by angle.
fn polar_about(points: &[[f64; 2]], c: &Vector2<f64>) -> Vec<(f64, f64)> {
    let mut p: Vec<(f64, f64)> = points
        .iter()
        .map(|[u, v]| {
            let d = Vector2::new(*u, *v) - c;
            (d.y.atan2(d.x), d.norm())
        })
        .collect();
    p.sort_by(|a, b| a.0.total_cmp(&b.0));
    p
}

/// The radius of a path (sorted by angle) at angle `t`, linear between its neighbours, around
/// the seam at ±π.
fn radius_at(path: &[(f64, f64)], t: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let k = path.partition_point(|(a, _)| *a < t);
    let (lo, hi) = match k {
        0 => ((path[path.len() - 1].0 - tau, path[path.len() - 1].1), path[0]),
        k if k == path.len() => (path[k - 1], (path[0].0 + tau, path[0].1)),
        k => (path[k - 1], path[k]),
    };
    if (hi.0 - lo.0).abs() < 1e-15 {
        return lo.1;
    }
    lo.1 + (hi.1 - lo.1) * (t - lo.0) / (hi.0 - lo.0)
}

/// ISO 230-4 for a clockwise and an anticlockwise run of the same nominal circle (points about
/// the nominal centre, mm): [`BidirectionalTest`].
pub fn iso230_4_both(clockwise: &[[f64; 2]], anticlockwise: &[[f64; 2]], nominal_radius: f64) -> Result<BidirectionalTest, CircleError> {
    let cw = iso230_4(clockwise, nominal_radius)?;
    let ccw = iso230_4(anticlockwise, nominal_radius)?;
    let all: Vec<[f64; 2]> = clockwise.iter().chain(anticlockwise).copied().collect();
    let (c, _) = least_squares_circle(&all)?;
    let (a, b) = (polar_about(clockwise, &c), polar_about(anticlockwise, &c));
    let radii = a.iter().chain(&b).map(|p| p.1);
    let (lo, hi) = radii.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| (lo.min(r), hi.max(r)));
    let h = a
        .iter()
        .map(|(t, r)| (r - radius_at(&b, *t)).abs())
        .chain(b.iter().map(|(t, r)| (r - radius_at(&a, *t)).abs()))
        .fold(0.0, f64::max);
    Ok(BidirectionalTest {
        clockwise: cw,
        anticlockwise: ccw,
        centre_offset_mm: [c.x, c.y],
        circular_deviation_g_both_mm: hi - lo,
        circular_hysteresis_h_mm: h,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// By hand. An off-centre circle: R = 100, the path the circle of radius 100 about
    /// (0.01, 0), measured at (100.01, 0), (0.01, ±100), (−99.99, 0): LSQ centre (0.01, 0),
    /// radius 100, G = 0, F_max = +0.01 (at 0°), F_min = −0.01 (at 180°). An ellipse about the
    /// nominal centre, (100.01, 0), (0, 99.99), (−100.01, 0), (0, −99.99): centre 0 by symmetry,
    /// LSQ radius 100, G = 0.02, F = ±0.01.
    #[test]
    fn circular_and_radial_deviation_by_hand() {
        let shifted = [[100.01, 0.0], [0.01, 100.0], [-99.99, 0.0], [0.01, -100.0]];
        let t = iso230_4(&shifted, 100.0).unwrap();
        assert!(
            (t.centre_offset_mm[0] - 0.01).abs() < 1e-12 && t.centre_offset_mm[1].abs() < 1e-12,
            "{t:?}"
        );
        assert!(
            (t.lsq_radius_mm - 100.0).abs() < 1e-12 && t.circular_deviation_g_mm < 1e-12,
            "{t:?}"
        );
        assert!(
            (t.radial_deviation_f_max_mm - 0.01).abs() < 1e-9 && (t.radial_deviation_f_min_mm + 0.01).abs() < 1e-9,
            "{t:?}"
        );
        let ellipse = [[100.01, 0.0], [0.0, 99.99], [-100.01, 0.0], [0.0, -99.99]];
        let t = iso230_4(&ellipse, 100.0).unwrap();
        assert!(t.centre_offset_mm.iter().all(|v| v.abs() < 1e-12), "{t:?}");
        assert!((t.lsq_radius_mm - 100.0).abs() < 1e-12, "{t:?}");
        assert!((t.circular_deviation_g_mm - 0.02).abs() < 1e-9, "{t:?}");
        assert!((t.radial_deviation_f_max_mm - 0.01).abs() < 1e-9 && (t.radial_deviation_f_min_mm + 0.01).abs() < 1e-9);
        assert!(
            (t.radial[1][0] - 90.0).abs() < 1e-12 && (t.radial[1][1] + 0.01).abs() < 1e-9,
            "{:?}",
            t.radial
        );
    }

    /// A simulated ballbar run: a 150 mm circle at 720 points on a machine whose x axis is 30 µm
    /// long over the radius (an ellipse of semi-axes 150.03 × 150), its path 20 µm off in x and
    /// −15 µm in y, 1 µm of noise. Expected: centre (0.020, −0.015), G ≈ 30 µm (the ellipse's
    /// difference of radii) within a few σ, LSQ radius ≈ 150.015, F_max ≈ 0.03 + 0.02 (at 0°),
    /// F_min ≈ −0.0177 (near 105°: min of 0.03 cos² a + 0.02 cos a − 0.015 sin a) less the noise.
    #[test]
    fn a_simulated_ballbar_run_gives_the_machine_errors() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2304);
        let noise = Normal::new(0.0, 0.001).unwrap();
        let (offset, r) = ([0.020, -0.015], 150.0);
        let readings: Vec<[f64; 2]> = (0..720)
            .map(|k| {
                let a = (k as f64 * 0.5).to_radians();
                let p = [150.03 * a.cos() + offset[0], 150.0 * a.sin() + offset[1]];
                // The ballbar reads the distance from the pivot, along the actual direction.
                let (d, ang) = (p[0].hypot(p[1]) + noise.sample(&mut rng), p[1].atan2(p[0]).to_degrees());
                [ang, d]
            })
            .collect();
        let t = iso230_4(&points_from_radii(&readings), r).unwrap();
        assert!(
            (t.centre_offset_mm[0] - 0.020).abs() < 2e-4 && (t.centre_offset_mm[1] + 0.015).abs() < 2e-4,
            "{:?}",
            t.centre_offset_mm
        );
        assert!((t.circular_deviation_g_mm - 0.030).abs() < 0.006, "G {}", t.circular_deviation_g_mm);
        assert!(
            (t.radial_deviation_f_max_mm - 0.050).abs() < 0.005,
            "F_max {}",
            t.radial_deviation_f_max_mm
        );
        assert!(
            t.radial_deviation_f_min_mm < -0.010 && t.radial_deviation_f_min_mm > -0.025,
            "F_min {}",
            t.radial_deviation_f_min_mm
        );
        assert!((t.lsq_radius_mm - 150.015).abs() < 1e-3, "{}", t.lsq_radius_mm);
    }

    /// By hand, both directions: the clockwise path a circle of radius 100.01 about the nominal
    /// centre, the anticlockwise one of radius 99.99, both measured at the same eight angles.
    /// Each alone is a perfect circle (G 0); together their least-squares centre is the nominal
    /// one by symmetry, G(b) = 100.01 − 99.99 = 0.02 and H = 0.02 at every angle. The
    /// anticlockwise path turned by 22.5° (measured between the clockwise angles) gives the same
    /// H: radii are interpolated along each path.
    #[test]
    fn both_directions_by_hand() {
        let ring = |r: f64, turn: f64| -> Vec<[f64; 2]> {
            (0..8)
                .map(|k| {
                    let a = (k as f64 * 45.0 + turn).to_radians();
                    [r * a.cos(), r * a.sin()]
                })
                .collect()
        };
        for turn in [0.0, 22.5] {
            let t = iso230_4_both(&ring(100.01, 0.0), &ring(99.99, turn), 100.0).unwrap();
            assert!(
                t.clockwise.circular_deviation_g_mm < 1e-9 && t.anticlockwise.circular_deviation_g_mm < 1e-9,
                "{t:?}"
            );
            assert!(t.centre_offset_mm.iter().all(|v| v.abs() < 1e-9), "{t:?}");
            assert!((t.circular_deviation_g_both_mm - 0.02).abs() < 1e-9, "{t:?}");
            assert!((t.circular_hysteresis_h_mm - 0.02).abs() < 1e-9, "{t:?}");
        }
        // The same path both ways: no hysteresis, G(b) the path's own G.
        let path = [[100.01, 0.0], [0.0, 99.99], [-100.01, 0.0], [0.0, -99.99]];
        let t = iso230_4_both(&path, &path, 100.0).unwrap();
        assert!(t.circular_hysteresis_h_mm < 1e-12, "{t:?}");
        assert!((t.circular_deviation_g_both_mm - 0.02).abs() < 1e-9, "{t:?}");
    }

    #[test]
    fn degenerate_circles_are_named() {
        assert_eq!(iso230_4(&[[1.0, 0.0], [0.0, 1.0]], 1.0), Err(CircleError::TooFewPoints(2)));
        assert!(matches!(
            iso230_4(&[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]], 1.0),
            Err(CircleError::Degenerate(_))
        ));
        assert_eq!(iso230_4(&[[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]], 0.0), Err(CircleError::Radius(0.0)));
    }
}
