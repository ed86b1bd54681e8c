//! A touch probe's touches on a virtual prototype: spheres, planes and a datum cube placed in
//! its workspace, each touched at the configurations of a candidate set that come nearest it,
//! moved onto the surface ([`super::onto`]).
use super::within_limits;
use crate::error::{CalibError, KinError};
use crate::measure::touch::FACE_NAMES;
use crate::measure::{Measurement, Observation, Touch};
use crate::model::kind::InputSpec;
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::{DVector, Translation3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

/// One artifact a probe touches: its frame (mm, base frame; a sphere's centre, a plane's frame
/// with `z` its normal, the cube's frame at its centre) and the touch a row records (the sphere's
/// diameter, the cube face, the probe's radius).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Touched {
    /// The artifact's frame.
    pub frame: Pose,
    /// What a touch on it records.
    pub touch: Touch,
}

impl Touched {
    /// A sphere of `diameter` (mm) at `centre`, touched by a tip of radius `probe`.
    pub fn sphere(sphere: usize, centre: Vector3<f64>, diameter: f64, probe: f64) -> Touched {
        Touched {
            frame: Pose::from_parts(Translation3::from(centre), UnitQuaternion::identity()),
            touch: Touch::Sphere { sphere, diameter, probe },
        }
    }

    /// The plane through `origin` with unit normal `normal`.
    pub fn plane(plane: usize, origin: Vector3<f64>, normal: Vector3<f64>, probe: f64) -> Touched {
        let rotation = UnitQuaternion::rotation_between(&Vector3::z(), &normal)
            .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
        Touched {
            frame: Pose::from_parts(Translation3::from(origin), rotation),
            touch: Touch::Plane { plane, probe },
        }
    }

    /// The six faces of a datum cube of `edge` (mm) in pose `cube`.
    pub fn cube(cube: Pose, edge: f64, probe: f64) -> Vec<Touched> {
        (0..6)
            .map(|face| Touched {
                frame: cube,
                touch: Touch::Face { face, edge, probe },
            })
            .collect()
    }

    /// Its name in messages (`plane 2`, `cube face +x`).
    fn name(&self) -> String {
        match self.touch {
            Touch::Face { face, .. } => format!("cube face {}", FACE_NAMES[face.min(5)]),
            t => format!("{} {}", t.artifact().0.name(), t.artifact().1),
        }
    }
}

/// What a probe touches, as a user states it: reference spheres of one diameter, planes (a point
/// on each and its normal), a datum cube (centre, rotation vector, edge), all in mm (rad for
/// the rotation) in the base frame, and the probe's tip radius. [`TouchSpec::artifacts`] checks
/// it and makes the [`Touched`] artifacts; one kind per set.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TouchSpec {
    /// The spheres' centres.
    pub spheres: Vec<Vector3<f64>>,
    /// The spheres' diameter (mm).
    pub sphere_diameter_mm: Option<f64>,
    /// The planes: a point on each and its normal (any length but zero).
    pub planes: Vec<(Vector3<f64>, Vector3<f64>)>,
    /// The datum cube: its centre, its rotation vector (rad) and its edge (mm).
    pub cube: Option<(Vector3<f64>, Vector3<f64>, f64)>,
    /// The probe's tip radius (mm; 0 for a pointed tip).
    pub probe_radius_mm: f64,
}

impl TouchSpec {
    /// The artifacts (one per sphere, plane or cube face) and their kind's name (`sphere`,
    /// `plane`, `cube face`). One-line errors: no artifact or more than one kind, a negative or
    /// missing radius, a diameter or edge under [`crate::instrument::touch::MIN_ARTIFACT_MM`]
    /// (metres?), a zero normal.
    pub fn artifacts(&self) -> Result<(&'static str, Vec<Touched>), CalibError> {
        let bad = |m: String| CalibError::InvalidOption(m);
        let r = self.probe_radius_mm;
        if !(r.is_finite() && r >= 0.0) {
            return Err(bad(format!(
                "probe radius {r} mm: the radius of the probe's tip ball is needed (mm, not negative; 0 for a pointed tip)"
            )));
        }
        let kinds = usize::from(!self.spheres.is_empty()) + usize::from(!self.planes.is_empty()) + usize::from(self.cube.is_some());
        if kinds != 1 {
            return Err(bad(format!(
                "give one kind of artifact per set (spheres, planes or a cube), got {kinds}"
            )));
        }
        let size = |what: &str, v: Option<f64>| {
            let v = v.unwrap_or(f64::NAN);
            if v.is_finite() && v >= crate::instrument::touch::MIN_ARTIFACT_MM {
                Ok(v)
            } else {
                Err(bad(format!(
                    "{what} {v}: under 1 mm is not a plausible size in mm (is it in metres?)"
                )))
            }
        };
        if !self.spheres.is_empty() {
            let d = size("sphere diameter", self.sphere_diameter_mm)?;
            return Ok((
                "sphere",
                self.spheres.iter().enumerate().map(|(k, c)| Touched::sphere(k, *c, d, r)).collect(),
            ));
        }
        if !self.planes.is_empty() {
            let planes = (self.planes.iter().enumerate())
                .map(|(k, (o, n))| {
                    let n = n
                        .try_normalize(1e-12)
                        .ok_or_else(|| bad(format!("plane {k}: its normal is zero")))?;
                    Ok(Touched::plane(k, *o, n, r))
                })
                .collect::<Result<_, CalibError>>()?;
            return Ok(("plane", planes));
        }
        let (centre, rotation, edge) = self.cube.expect("one kind, checked above");
        let edge = size("cube edge", Some(edge))?;
        Ok(("cube face", Touched::cube(crate::se3::pose_from_parts(centre, rotation), edge, r)))
    }
}

/// `per_artifact` touches on each of `artifacts` by `truth` at random configurations: the
/// nearest of `30 · per_artifact` per artifact, drawn within the limits of `inputs` from `rng`
/// ([`touch_rows`], noise σ `noise_mm` along each normal).
pub fn random_touches<R: rand::Rng>(
    truth: &dyn Mechanism,
    inputs: &[InputSpec],
    artifacts: &[Touched],
    per_artifact: usize,
    noise_mm: f64,
    rng: &mut R,
) -> Result<Vec<Measurement>, CalibError> {
    let candidates = crate::simulate::random_configurations(truth, inputs, 30 * per_artifact * artifacts.len(), rng)
        .map_err(|source| CalibError::Kinematics { pose: 0, source })?;
    touch_rows(truth, &candidates, artifacts, per_artifact, noise_mm, rng.next_u64(), inputs)
}

/// `per_artifact` touches on each of `artifacts` by `truth` (the real machine with its probe):
/// for each artifact the configurations of `candidates` whose tool point is nearest its surface
/// (each used once), moved onto it (the tip's centre `r` off the surface plus noise of σ
/// `noise_mm` along the normal), within the limits of `inputs`. One [`Observation::Touch`] row
/// each; an error names an artifact fewer configurations reached.
pub fn touch_rows(
    truth: &dyn Mechanism,
    candidates: &[Vec<f64>],
    artifacts: &[Touched],
    per_artifact: usize,
    noise_mm: f64,
    seed: u64,
    inputs: &[InputSpec],
) -> Result<Vec<Measurement>, CalibError> {
    let (mut rng, noise) = seeded_noise(noise_mm, seed)?;
    let points: Vec<Option<Vector3<f64>>> = candidates
        .iter()
        .map(|q| truth.forward(q).ok().map(|t| t.translation.vector))
        .collect();
    let mut used = vec![false; candidates.len()];
    let fixed = approach_inputs(candidates.first().map_or(0, Vec::len), inputs);
    let mut out = Vec::new();
    for a in artifacts {
        let off = |p: &Vector3<f64>| a.touch.residual(&a.frame.inverse_transform_point(&(*p).into()).coords);
        let mut order: Vec<(usize, f64)> = (points.iter().enumerate())
            .filter_map(|(i, p)| p.map(|p| (i, off(&p).abs())))
            .collect();
        order.sort_by(|x, y| x.1.total_cmp(&y.1));
        let mut found = 0;
        for (i, _) in order {
            if found == per_artifact {
                break;
            }
            if used[i] {
                continue;
            }
            let e = noise.sample(&mut rng);
            let residual = |t: &Pose| DVector::from_element(1, off(&t.translation.vector) + e);
            let Some((q, _)) = super::onto(truth, &candidates[i], &fixed, 30, residual, |r| r[0].abs() < 1e-10) else {
                continue;
            };
            let Some(q) = within_limits(q, inputs) else { continue };
            used[i] = true;
            out.push(Measurement {
                q,
                obs: Observation::Touch(a.touch),
                joints: Vec::new(),
            });
            found += 1;
        }
        if found < per_artifact {
            return Err(CalibError::Kinematics {
                pose: out.len(),
                source: KinError::Unreachable(format!(
                    "{}: {found} of {per_artifact} configurations reached it (move it into the workspace, or draw more configurations)",
                    a.name()
                )),
            });
        }
    }
    Ok(out)
}

/// A touch plan (rows of [`crate::design::plan_touches`], planned on the nominal) measured on
/// `truth`: each planned configuration moved onto its artifact of `artifacts` (the one with the
/// row's sphere, plane or cube face) by `truth`, the tip's centre `r` off the surface plus noise
/// of σ `noise_mm` along the normal (seed `seed`), within the limits of `inputs`: what a probe
/// approaching the surface from the planned configuration records. A row whose artifact is not
/// given, or that the truth cannot move onto it, is an error naming the row.
pub fn touch_planned(
    truth: &dyn Mechanism,
    planned: &[Measurement],
    artifacts: &[Touched],
    noise_mm: f64,
    seed: u64,
    inputs: &[InputSpec],
) -> Result<Vec<Measurement>, CalibError> {
    let (mut rng, noise) = seeded_noise(noise_mm, seed)?;
    let fixed = approach_inputs(planned.first().map_or(0, |m| m.q.len()), inputs);
    let unreachable = |i: usize, why: String| CalibError::Kinematics {
        pose: i,
        source: KinError::Unreachable(why),
    };
    planned
        .iter()
        .enumerate()
        .map(|(i, m)| {
            let Observation::Touch(touch) = m.obs else {
                return Err(CalibError::InvalidOption(format!("row {i}: not a touch")));
            };
            let a = artifacts.iter().find(|a| a.touch == touch).ok_or_else(|| {
                CalibError::InvalidOption(format!(
                    "row {i}: it touches an artifact not given (a different size, radius or number)"
                ))
            })?;
            let off = |p: &Vector3<f64>| a.touch.residual(&a.frame.inverse_transform_point(&(*p).into()).coords);
            let e = noise.sample(&mut rng);
            let residual = |t: &Pose| DVector::from_element(1, off(&t.translation.vector) + e);
            let (q, _) = super::onto(truth, &m.q, &fixed, 30, residual, |r| r[0].abs() < 1e-10)
                .ok_or_else(|| unreachable(i, format!("{}: the machine does not reach it from this configuration", a.name())))?;
            let q = within_limits(q, inputs).ok_or_else(|| unreachable(i, format!("{}: reached only beyond the limits", a.name())))?;
            Ok(Measurement {
                q,
                obs: m.obs.clone(),
                joints: Vec::new(),
            })
        })
        .collect()
}

/// The generator seeded `seed` and the normal noise of σ `noise_mm` (0 below 0) simulated
/// instrument rows draw (touches here, planned rows in [`crate::instrument::measure_planned`]).
pub(crate) fn seeded_noise(noise_mm: f64, seed: u64) -> Result<(rand_chacha::ChaCha8Rng, Normal<f64>), CalibError> {
    let noise = Normal::new(0.0, noise_mm.max(0.0)).map_err(|e| CalibError::InvalidOption(e.to_string()))?;
    Ok((rand_chacha::ChaCha8Rng::seed_from_u64(seed), noise))
}

/// Which of `n` inputs are approach directions (±1, [`InputSpec::approach_of`]): they stay as
/// drawn while a configuration is moved onto a surface.
fn approach_inputs(n: usize, inputs: &[InputSpec]) -> Vec<bool> {
    (0..n).map(|k| inputs.get(k).is_some_and(|i| i.approach_of.is_some())).collect()
}
