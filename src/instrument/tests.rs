//! Unit tests of the instrument kinds.
use super::*;
use crate::measure::{residual, residual_jacobian, Touch};
use crate::model::builtin::irb120;
use crate::model::framed::Framed;
use crate::se3;

fn artifact() -> Artifact<Framed<crate::model::chain::SerialChain>> {
    let framed = Framed::new(
        irb120(),
        Pose::identity(),
        se3::pose_from_parts(Vector3::new(15.0, -10.0, 120.0), Vector3::new(0.1, 0.2, -0.3)),
    );
    let points = vec![
        ArtifactPoint {
            kind: PointKind::Seat,
            id: 0,
            centre: Vector3::new(400.0, 50.0, 200.0),
            zero: None,
            rotation: None,
        },
        ArtifactPoint {
            kind: PointKind::Pivot,
            id: 3,
            centre: Vector3::new(350.0, -80.0, 150.0),
            zero: None,
            rotation: None,
        },
        // A draw-wire's anchor: readings relative to an unknown zero.
        ArtifactPoint {
            kind: PointKind::Pivot,
            id: 5,
            centre: Vector3::new(300.0, 120.0, 100.0),
            zero: Some(Zero {
                value: 180.0,
                reference: 950.0,
            }),
            rotation: None,
        },
        // A probe's artifacts: a sphere, a plane (tilted), the datum cube (turned).
        ArtifactPoint {
            kind: PointKind::Sphere,
            id: 2,
            centre: Vector3::new(380.0, 60.0, 90.0),
            zero: None,
            rotation: None,
        },
        ArtifactPoint {
            kind: PointKind::Plane,
            id: 0,
            centre: Vector3::new(420.0, -30.0, 80.0),
            zero: None,
            rotation: Some(nalgebra::UnitQuaternion::from_scaled_axis(Vector3::new(0.2, -0.3, 0.1))),
        },
        ArtifactPoint {
            kind: PointKind::Cube,
            id: 0,
            centre: Vector3::new(360.0, 40.0, 60.0),
            zero: None,
            rotation: Some(nalgebra::UnitQuaternion::from_scaled_axis(Vector3::new(-0.4, 0.1, 0.7))),
        },
    ];
    Artifact {
        inner: framed,
        points,
        pairs: vec![(0, 1)],
    }
}

/// The relative pose's spatial Jacobian, and the seat and distance residual rows built from
/// it, against central differences of the retraction (every column: the machine's, the
/// frames', the points').
#[test]
fn jacobians_match_finite_differences() {
    let m = artifact();
    let h = 1e-6;
    for (k, obs) in [
        (0.0, Observation::Seat(0)),
        (
            1.0,
            Observation::Distance {
                pivot: 3,
                length: 250.0,
                relative: false,
            },
        ),
        // A reading relative to the anchor's unknown zero (plus its reference).
        (
            2.0,
            Observation::Distance {
                pivot: 5,
                length: 1020.0,
                relative: true,
            },
        ),
        // A tracker row (no artifact point): a position and a pose in the tracker's frame.
        (NO_POINT, Observation::Position(Vector3::new(400.0, 0.0, 300.0))),
        // (measured where predicted: the rotation rows' derivative is exact at zero residual)
        (
            NO_POINT,
            Observation::Pose(m.forward(&[0.3, -0.4, 0.5, 0.9, -1.1, 0.7, NO_POINT]).unwrap()),
        ),
        (
            3.0,
            Observation::Touch(Touch::Sphere {
                sphere: 2,
                diameter: 25.0,
                probe: 1.5,
            }),
        ),
        (4.0, Observation::Touch(Touch::Plane { plane: 0, probe: 1.5 })),
        (
            5.0,
            Observation::Touch(Touch::Face {
                face: 3,
                edge: 50.0,
                probe: 1.5,
            }),
        ),
        // The known distance between the first two points (the pair's row).
        (
            6.0,
            Observation::Distance {
                pivot: usize::MAX,
                length: 60.0,
                relative: false,
            },
        ),
    ] {
        let q = [0.3, -0.4, 0.5, 0.9, -1.1, 0.7, k];
        let (t, jac) = m.forward_with_jacobian(&q).unwrap();
        let rows = residual_jacobian(&obs, &t, &jac);
        for c in 0..m.n_params() {
            let (tp, tm) = crate::model::retracted_poses(&m, &q, c, h);
            let fd = (se3::log(&(tp * t.inverse())) - se3::log(&(tm * t.inverse()))) / (2.0 * h);
            let err = (fd - jac.column(c)).norm();
            assert!(err < 1e-5 * (1.0 + jac.column(c).norm()), "point {k}, column {c}: {err:e}");
            // Residual = measured − predicted: its derivative is minus the rows.
            let (rp, rm) = (residual(&obs, &tp), residual(&obs, &tm));
            for r in 0..rows.nrows() {
                let fd_row = -(rp[r] - rm[r]) / (2.0 * h);
                let err = (fd_row - rows[(r, c)]).abs();
                assert!(err < 1e-5 * (1.0 + rows[(r, c)].abs()), "point {k}, row {r}, column {c}: {err:e}");
            }
        }
    }
}

#[test]
fn a_seat_with_one_row_and_an_unknown_point_index_are_clear_errors() {
    let row = |obs| Measurement {
        q: vec![0.0; 6],
        obs,
        joints: Vec::new(),
    };
    let e = index_points(
        &[row(Observation::Seat(2)), row(Observation::Seat(4)), row(Observation::Seat(4))],
        &[],
    )
    .unwrap_err();
    assert!(e.to_string().contains("seat 2 has 1 row"), "{e}");
    // A tracker row among seat rows refers to no artifact point.
    let (points, _, indexed) = index_points(
        &[
            row(Observation::Seat(0)),
            row(Observation::Position(Vector3::zeros())),
            row(Observation::Seat(0)),
        ],
        &[],
    )
    .unwrap()
    .unwrap();
    assert_eq!((points.len(), indexed[1].q[6], indexed[2].q[6]), (1, NO_POINT, 0.0));
    let m = artifact();
    let e = m.forward(&[0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 9.0]).unwrap_err();
    assert!(e.to_string().contains("artifact point index 9"), "{e}");
    let (points, _, indexed) = index_points(&[row(Observation::Seat(5)), row(Observation::Seat(5))], &[])
        .unwrap()
        .unwrap();
    assert_eq!((points.len(), indexed[1].q.len()), (1, 7));
    let two = [
        row(Observation::Seat(5)),
        row(Observation::Seat(5)),
        row(Observation::Seat(6)),
        row(Observation::Seat(6)),
    ];
    let e = index_points(&two, &[SeatDistance { a: 5, b: 9, length: 50.0 }]).unwrap_err();
    assert!(e.to_string().contains("no seat 9"), "{e}");
    let (_, pairs, indexed) = index_points(&two, &["6:5:50".parse().unwrap()]).unwrap().unwrap();
    assert_eq!((pairs, indexed.len(), indexed[4].q[6]), (vec![(1, 0)], 5, 2.0));
    assert!("5:5:50".parse::<SeatDistance>().is_err() && "5:6".parse::<SeatDistance>().is_err());
}

/// The sphere fit finds a centre from exact lengths, and the offset fit finds the tool
/// point's offset and the pivot from a start 120 mm off.
#[test]
fn pivots_and_the_tool_offset_start_from_the_lengths() {
    let truth = artifact();
    let c = truth.points[1].centre;
    let rows: Vec<(usize, Pose, f64)> = (0..30)
        .map(|i| {
            let f = i as f64;
            let q = [
                0.2 * f.sin(),
                -0.3 + 0.1 * f.cos(),
                0.4,
                0.5 * (2.0 * f).sin(),
                -1.0 + 0.2 * f.cos(),
                0.3 * f,
            ];
            let flange = truth.inner.inner.forward(&q).unwrap();
            let tip = (flange * truth.inner.tool).translation.vector;
            (1, flange, (tip - c).norm())
        })
        .collect();
    let sphere: Vec<(Vector3<f64>, f64)> = rows
        .iter()
        .map(|(_, p, _)| (p * truth.inner.tool).translation.vector)
        .zip(rows.iter().map(|r| r.2))
        .collect();
    assert!((sphere_centre(&sphere).unwrap() - c).norm() < 1e-8);
    let mut points = truth.points.clone();
    points[1].centre += Vector3::new(30.0, -20.0, 10.0);
    let (t, cost) = fit_offset_and_pivots(&rows, Vector3::zeros(), &mut points);
    assert!((t - truth.inner.tool.translation.vector).norm() < 1e-6, "{t:?}");
    assert!((points[1].centre - c).norm() < 1e-6);
    assert!(cost < 1e-12, "{cost:e}");
}

/// With lengths that no sphere fits exactly (noise), the centre is the least-squares one: every
/// small move of it raises the sum of squared length residuals (a Gauss–Newton step of the wrong
/// sign walked away from it, and placed a pivot kilometres off on a machine that never turns).
#[test]
fn a_sphere_centre_is_the_least_squares_one_when_lengths_disagree() {
    let c = Vector3::new(80.0, 2.0, 20.0);
    let rows: Vec<(Vector3<f64>, f64)> = (0..40)
        .map(|i| {
            let f = i as f64;
            let p = Vector3::new(30.0 * (0.7 * f).sin(), 25.0 * (1.3 * f).cos(), 90.0 + 20.0 * (0.4 * f).sin());
            // Errors of ±0.5 mm, far above round-off.
            (p, (p - c).norm() + 0.5 * (2.1 * f).sin())
        })
        .collect();
    let cost = |x: &Vector3<f64>| rows.iter().map(|(p, l)| (l - (p - x).norm()).powi(2)).sum::<f64>();
    let found = sphere_centre(&rows).unwrap();
    assert!((found - c).norm() < 5.0, "{found:?}");
    for d in [
        Vector3::x(),
        Vector3::y(),
        Vector3::z(),
        -Vector3::x(),
        -Vector3::y(),
        -Vector3::z(),
    ] {
        assert!(cost(&found) < cost(&(found + 1e-3 * d)), "{d:?}");
    }
}

/// A pivot with an unknown zero: the centre and the zero from exact readings (some negative),
/// and too few rows or rows that do not place it give none.
#[test]
fn a_pivot_and_its_zero_start_from_the_readings() {
    let (c, zero) = (Vector3::new(80.0, 2.0, 20.0), 130.0);
    let rows: Vec<(Vector3<f64>, f64)> = (0..20)
        .map(|i| {
            let f = i as f64;
            let p = Vector3::new(60.0 * (0.7 * f).sin(), 50.0 * (1.3 * f).cos(), 90.0 + 40.0 * (0.4 * f).sin());
            (p, (p - c).norm() - zero)
        })
        .collect();
    assert!(rows.iter().any(|r| r.1 < 0.0));
    let (found, e) = sphere_and_zero(&rows).unwrap();
    assert!((found - c).norm() < 1e-8 && (e - zero).abs() < 1e-8, "{found:?} {e}");
    assert!(sphere_and_zero(&rows[..4]).is_none());
}

/// Exact touches of the true tool points on a sphere, a plane and the cube's faces place each
/// artifact where it is ([`touch::place`]), and the touch kinds' one-line errors.
#[test]
fn touched_artifacts_start_from_the_touches() {
    let truth = artifact();
    let probe = 1.5;
    let mut obs = Vec::new();
    let mut poses = Vec::new();
    // Tool points on each surface: a sphere of 25 mm, the plane, the cube's +x, -y and +z faces.
    for i in 0..27 {
        let f = i as f64;
        let (u, v) = ((0.7 * f).sin(), (1.3 * f).cos());
        let (k, t, p) = match i % 3 {
            0 => {
                let d = Vector3::new(u, v, 1.0 + 0.3 * (0.4 * f).sin()).normalize();
                let t = Touch::Sphere {
                    sphere: 2,
                    diameter: 25.0,
                    probe,
                };
                (3, t, nalgebra::Point3::from(truth.points[3].centre + d * (12.5 + probe)))
            }
            1 => (
                4,
                Touch::Plane { plane: 0, probe },
                truth.frame(4) * nalgebra::Point3::new(40.0 * u, 30.0 * v, probe),
            ),
            _ => {
                let face = [0, 3, 4][(i / 3) % 3];
                let n = crate::measure::touch::face_normal(face);
                let q =
                    n * (25.0 + probe) + (Vector3::new(u, v, 0.5 * u * v) * 20.0 - n * n.dot(&(Vector3::new(u, v, 0.5 * u * v) * 20.0)));
                (
                    5,
                    Touch::Face { face, edge: 50.0, probe },
                    truth.frame(5) * nalgebra::Point3::from(q),
                )
            }
        };
        // The flange 120 mm beyond the tool point, on the surface's outer side.
        let pose = Pose::from_parts(Translation3::from(p.coords), nalgebra::UnitQuaternion::identity());
        let outward = match t {
            Touch::Sphere { .. } => (p.coords - truth.points[3].centre).normalize(),
            Touch::Plane { .. } => truth.frame(4).rotation * Vector3::z(),
            Touch::Face { face, .. } => truth.frame(5).rotation * crate::measure::touch::face_normal(face),
        };
        poses.push((k, pose, p.coords + 120.0 * outward));
        obs.push(Observation::Touch(t));
    }
    let rows: Vec<_> = poses
        .iter()
        .zip(&obs)
        .map(|((k, pose, flange), o)| (*k, *pose, *flange, o))
        .collect();
    let mut points = truth.points.clone();
    for p in &mut points[3..] {
        p.centre = Vector3::zeros();
        p.rotation = p.rotation.map(|_| nalgebra::UnitQuaternion::identity());
    }
    touch::place(&rows, &mut points).unwrap();
    assert!((points[3].centre - truth.points[3].centre).norm() < 1e-8, "{:?}", points[3].centre);
    // The plane: its normal and its offset (its origin anywhere on it).
    let (n, n0) = (points[4].rotation.unwrap() * Vector3::z(), truth.frame(4).rotation * Vector3::z());
    assert!(
        (n - n0).norm() < 1e-9 && n0.dot(&(points[4].centre - truth.points[4].centre)).abs() < 1e-8,
        "{n:?}"
    );
    let cube = truth.frame(5).inverse() * Pose::from_parts(Translation3::from(points[5].centre), points[5].rotation.unwrap());
    assert!(se3::log(&cube).norm() < 1e-8, "{cube:?}");
    // Errors: a plane touched twice, a negative probe radius, a diameter in metres, faces of two sizes.
    let row = |t| Measurement {
        q: vec![0.0; 6],
        obs: Observation::Touch(t),
        joints: Vec::new(),
    };
    let plane = |plane| row(Touch::Plane { plane, probe });
    let e = index_points(&[plane(0), plane(0), plane(0), plane(1), plane(1)], &[]).unwrap_err();
    assert!(e.to_string().contains("plane 1 has 2 rows"), "{e}");
    let e = index_points(&[row(Touch::Plane { plane: 0, probe: -1.0 })], &[]).unwrap_err();
    assert!(e.to_string().contains("probe radius -1"), "{e}");
    let e = index_points(
        &[row(Touch::Sphere {
            sphere: 0,
            diameter: 0.025,
            probe,
        })],
        &[],
    )
    .unwrap_err();
    assert!(
        e.to_string().contains("sphere 0: sphere diameter 0.025 mm") && e.to_string().contains("metres"),
        "{e}"
    );
    let face = |face, edge| row(Touch::Face { face, edge, probe });
    let e = index_points(&[face(0, 50.0), face(0, 50.0), face(0, 51.0)], &[]).unwrap_err();
    assert!(e.to_string().contains("cube 0: its rows give cube edges 50 and 51 mm"), "{e}");
    let e = index_points(&[face(0, 50.0), face(0, 50.0), face(0, 50.0), face(2, 50.0)], &[]).unwrap_err();
    assert!(e.to_string().contains("cube face 2 (+y) has 1 touch;"), "{e}");
    let e = index_points(&[face(7, 50.0)], &[]).unwrap_err();
    assert!(e.to_string().contains("cube face 7"), "{e}");
    // Three touches on a line do not place a plane.
    let line: Vec<_> = (0..3)
        .map(|i| (0, Pose::translation(i as f64, 0.0, 0.0), Vector3::new(0.0, 0.0, 100.0), &obs[1]))
        .collect();
    let mut one = vec![crate::instrument::zero::pivot_point(PointKind::Plane, 0, None)];
    let e = touch::place(&line, &mut one).unwrap_err();
    assert!(e.to_string().contains("plane 0: its touches lie on a line"), "{e}");
}

/// Two planes' touches whose probe centres all lie in one plane (what a point the machine keeps
/// in a plane gives) collapse; the same touches with one plane's centres lifted off it do not.
#[test]
fn touched_planes_that_are_one_plane_are_seen() {
    let plane = |k: usize| Observation::Touch(Touch::Plane { plane: k, probe: 1.5 });
    let (p0, p1) = (plane(0), plane(1));
    let at = |x: f64, y: f64, z: f64| se3::pose_from_parts(Vector3::new(x, y, z), Vector3::zeros());
    let point = |id: usize| ArtifactPoint {
        kind: PointKind::Plane,
        id,
        centre: Vector3::zeros(),
        zero: None,
        rotation: None,
    };
    let points = [point(0), point(1)];
    // Every tip at z = 0: plane 0 along x, plane 1 along y.
    let flat: Vec<touch::TouchRow> = [(0, at(0.0, 0.0, 0.0)), (0, at(50.0, 10.0, 0.0)), (0, at(100.0, 0.0, 0.0))]
        .into_iter()
        .map(|(k, pose)| (k, pose, Vector3::zeros(), &p0))
        .chain(
            [at(0.0, 50.0, 0.0), at(10.0, 100.0, 0.0), at(-20.0, 80.0, 0.0)]
                .into_iter()
                .map(|pose| (1, pose, Vector3::zeros(), &p1)),
        )
        .collect();
    assert!(touch::planes_collapse(&flat, &Vector3::zeros(), &points));
    // Plane 1 tilted up out of z = 0.
    let lifted: Vec<touch::TouchRow> = flat
        .iter()
        .map(|&(k, pose, f, obs)| {
            (
                k,
                if k == 1 {
                    at(pose.translation.x, pose.translation.y, pose.translation.y)
                } else {
                    pose
                },
                f,
                obs,
            )
        })
        .collect();
    assert!(!touch::planes_collapse(&lifted, &Vector3::zeros(), &points));
    // A tool-point offset moves every tip alike: still one plane.
    assert!(touch::planes_collapse(&flat, &Vector3::new(0.0, 0.0, 120.0), &points));
}
