//! G-code arcs (`G2` clockwise, `G3` anticlockwise) in the plane `G17` (XY), `G18` (ZX) or `G19`
//! (YZ), centre given by the offsets `I J K` from the start or by the radius `R` (negative: the
//! arc over 180°), an axis normal to the plane moving with the angle (a helix), and any other
//! axis (`A B`) too: linearised into chords within a chord error (the sagitta).
use std::f64::consts::{FRAC_PI_2, TAU};

/// How an arc's centre is given.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Centre {
    /// `I J K`: offsets from the start (mm) along X, Y, Z; those not written are 0.
    Offsets([f64; 3]),
    /// `R`: the radius (mm); negative for the arc over 180°.
    Radius(f64),
}

/// The plane's axes (first, second, normal) of `G17`, `G18`, `G19`.
pub fn plane_axes(plane: u8) -> [usize; 3] {
    match plane {
        18 => [2, 0, 1],
        19 => [1, 2, 0],
        _ => [0, 1, 2],
    }
}

/// A linearised arc.
#[derive(Debug, Clone, PartialEq)]
pub struct Chords {
    /// The points after the start, the last the arc's end, each with its fraction of the arc.
    pub points: Vec<([f64; 5], f64)>,
    /// The largest distance of a chord from the arc (mm).
    pub sagitta: f64,
    /// The radius (mm).
    pub radius: f64,
}

/// The arc from `start` to `end` (X Y Z mm, A B deg) in `plane`, clockwise or not, as chords
/// within `tolerance` mm of it (the radius changing from the start's to the end's along it);
/// refused when the end is more than half the tolerance off the circle through the start (or an
/// `R` too short for the chord by as much).
pub fn linearise(start: &[f64; 5], end: &[f64; 5], plane: u8, clockwise: bool, centre: Centre, tolerance: f64) -> Result<Chords, String> {
    let mismatch = tolerance / 2.0;
    let [u, v, _] = plane_axes(plane);
    let (su, sv, eu, ev) = (start[u], start[v], end[u], end[v]);
    let (cu, cv) = match centre {
        Centre::Offsets(o) => (su + o[u], sv + o[v]),
        Centre::Radius(r) => {
            let (du, dv) = (eu - su, ev - sv);
            let d = du.hypot(dv);
            if d == 0.0 {
                return Err("an arc given by R whose start and end are the same point (the circle is not determined)".into());
            }
            if d > 2.0 * r.abs() + mismatch {
                return Err(format!(
                    "an arc's radius R {} is shorter than half the distance to its end ({:.4} mm)",
                    r.abs(),
                    d / 2.0
                ));
            }
            let h = (r * r - d * d / 4.0).max(0.0).sqrt();
            // Left of the chord for an anticlockwise arc under 180° (and a clockwise over 180°).
            let left = clockwise == (r < 0.0);
            let s = if left { 1.0 } else { -1.0 };
            let (mu, mv) = (su + du / 2.0, sv + dv / 2.0);
            (mu - s * h * dv / d, mv + s * h * du / d)
        }
    };
    let rs = (su - cu).hypot(sv - cv);
    let re = (eu - cu).hypot(ev - cv);
    if rs == 0.0 {
        return Err("an arc of radius 0".into());
    }
    if (rs - re).abs() > mismatch {
        return Err(format!(
            "an arc whose end is {:.4} mm off its circle (radius {rs:.4} mm at the start, {re:.4} mm at the end): beyond the tolerance {mismatch} mm",
            (rs - re).abs()
        ));
    }
    let (a0, a1) = ((sv - cv).atan2(su - cu), (ev - cv).atan2(eu - cu));
    let mut sweep = if clockwise { a0 - a1 } else { a1 - a0 };
    sweep = sweep.rem_euclid(TAU);
    if sweep < 1e-12 {
        sweep = TAU; // the same start and end: a full circle
    }
    let sweep = if clockwise { -sweep } else { sweep };
    // Chords of angle δ stay within r(1 − cos(δ/2)) of the arc; a quarter turn at most.
    let radius = rs.max(re);
    let chord_tolerance = tolerance - (rs - re).abs();
    let per = if chord_tolerance >= radius {
        FRAC_PI_2
    } else {
        (2.0 * (1.0 - chord_tolerance / radius).acos()).min(FRAC_PI_2)
    };
    let n = ((sweep.abs() / per).ceil() as usize).max(1);
    let delta = sweep.abs() / n as f64;
    let sagitta = radius * (1.0 - (delta / 2.0).cos()) + (rs - re).abs();
    let mut points = Vec::with_capacity(n);
    for k in 1..=n {
        let f = k as f64 / n as f64;
        if k == n {
            points.push((*end, 1.0));
            continue;
        }
        let a = a0 + sweep * f;
        let r = rs + (re - rs) * f;
        let mut p = [0.0; 5];
        for (i, x) in p.iter_mut().enumerate() {
            *x = start[i] + (end[i] - start[i]) * f;
        }
        p[u] = cu + r * a.cos();
        p[v] = cv + r * a.sin();
        points.push((p, f));
    }
    Ok(Chords { points, sagitta, radius })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quarter_circle_by_offsets_and_by_radius() {
        // From (10, 0) anticlockwise about the origin to (0, 10).
        let (s, e) = ([10.0, 0.0, 5.0, 0.0, 0.0], [0.0, 10.0, 7.0, 0.0, 0.0]);
        for c in [Centre::Offsets([-10.0, 0.0, 0.0]), Centre::Radius(10.0)] {
            let ch = linearise(&s, &e, 17, false, c, 0.001).unwrap();
            assert!(ch.sagitta <= 0.001);
            assert_eq!(ch.points.last().unwrap().0, e);
            for (p, f) in &ch.points {
                assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-9);
                assert!(p[0] > -1e-9 && p[1] > -1e-9, "{p:?}");
                assert!((p[2] - (5.0 + 2.0 * f)).abs() < 1e-9, "helix");
            }
        }
        // Clockwise the long way round (R negative: over 180°).
        let ch = linearise(&s, &e, 17, true, Centre::Radius(-10.0), 0.01).unwrap();
        assert!(ch.points.iter().any(|(p, _)| p[0] < -9.0));
        // The end off the circle.
        let bad = [0.0, 10.5, 5.0, 0.0, 0.0];
        assert!(linearise(&s, &bad, 17, false, Centre::Offsets([-10.0, 0.0, 0.0]), 0.01).is_err());
        // G18: the plane ZX.
        let (s, e) = ([0.0, 3.0, 10.0, 0.0, 0.0], [10.0, 3.0, 0.0, 0.0, 0.0]);
        let ch = linearise(&s, &e, 18, false, Centre::Offsets([0.0, 0.0, -10.0]), 0.01).unwrap();
        assert!(ch.points.iter().all(|(p, _)| (p[0].hypot(p[2]) - 10.0).abs() < 1e-9 && p[1] == 3.0));
    }
}
