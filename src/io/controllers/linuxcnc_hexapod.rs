//! LinuxCNC `genhexkins` parameters of a Stewart platform (6-UPS), as HAL `setp` lines.
//!
//! # Convention (genhexkins)
//! Strut `N` (0…5) joins the base joint `genhexkins.base.N.{x,y,z}` (base = world frame) to the
//! platform joint `genhexkins.platform.N.{x,y,z}` (platform frame); mm. With the platform pose
//! `(p, R)` (genhexkins: X Y Z and A B C, `R = Rz(C)·Ry(B)·Rx(A)`), joint `N` of genhexkins is
//! the strut length `|p + R·platform.N − base.N|`. kinecal's input `N` is the actuator's
//! position, the strut length plus `offset.N.offset` (LinuxCNC's `offset` component,
//! `out = in + offset`, between the joint and its motor; equivalently, shift
//! `[JOINT_N] HOME_OFFSET` by it). Values with 10 decimals (mm).
//!
//! # Export ([`export`])
//! A `kind = "stewart"` model is exactly genhexkins's model (its `U_i`, `S_i` and `L0_i`,
//! `offset = −L0`): closed form. A `kind = "limbs"` platform with six actuated inputs and a
//! full-pose task is projected leg by leg: over configurations spread over the workspace, the
//! two joint points and the offset that best reproduce the model's inputs from the platform
//! pose (least squares on strut lengths, started from the exact solution of the linearised
//! equations); limb geometry beyond two points and a length (an actuator axis off the joint
//! centres, joint axis errors) is reported with its strut-length residual. The difference
//! printed is the platform pose of genhexkins's forward kinematics (Newton from the model's
//! pose) against the model's, at the model's inputs. The measurement and tool frames of a
//! calibration are not written (genhexkins's world is the base frame, its pose the platform's).
//!
//! # Import ([`import`])
//! A `kind = "stewart"` model of the 42 numbers; its home is the pose at zero inputs (found by
//! the forward kinematics from above the base centroid), strokes ±120 mm, workspace ±40 mm and
//! ±8° about the home (the file does not carry them: edit the model file).
use super::{fixed, number, strip_comment, ControllerError, Export, Projection};
use crate::error::KinError;
use crate::io::model_file::{MechanismSpec, ModelFile};
use crate::model::closed::Workspace;
use crate::model::presets::stewart::Stewart;
use crate::model::projection::{least_squares, spread_configurations, PoseDifference};
use crate::model::Mechanism;
use crate::se3::{self, Pose};
use nalgebra::{DMatrix, DVector, Matrix6, Point3, Vector3, Vector6};
use std::fmt::Write as _;

const DECIMALS: usize = 10;

/// genhexkins's parameters (mm).
#[derive(Debug, Clone, PartialEq)]
pub struct Genhex {
    /// Base joints, base frame.
    pub base: [[f64; 3]; 6],
    /// Platform joints, platform frame.
    pub platform: [[f64; 3]; 6],
    /// `offset.N.offset`: actuator position minus strut length.
    pub offset: [f64; 6],
}

impl Genhex {
    /// Strut lengths at platform pose `t`.
    pub fn lengths(&self, t: &Pose) -> [f64; 6] {
        std::array::from_fn(|i| (t.transform_point(&Point3::from(self.platform[i])).coords - Vector3::from(self.base[i])).norm())
    }

    /// The actuator positions (kinecal's inputs) at platform pose `t`.
    pub fn inputs(&self, t: &Pose) -> [f64; 6] {
        let l = self.lengths(t);
        std::array::from_fn(|i| l[i] + self.offset[i])
    }

    /// The platform pose at actuator positions `q`, by Newton from `start`.
    pub fn forward(&self, q: &[f64], start: &Pose) -> Result<Pose, KinError> {
        let mut t = *start;
        for _ in 0..50 {
            let f = |t: &Pose| -> Vector6<f64> {
                let l = self.inputs(t);
                Vector6::from_fn(|i, _| l[i] - q[i])
            };
            let r = f(&t);
            if r.norm() < 1e-11 {
                return Ok(t);
            }
            let mut j = Matrix6::zeros();
            for c in 0..6 {
                let mut d = Vector6::zeros();
                d[c] = 1e-6;
                let col = (f(&(t * se3::exp(&d))) - f(&(t * se3::exp(&-d)))) / 2e-6;
                j.set_column(c, &col);
            }
            let step = j.lu().solve(&-r).ok_or_else(|| KinError::Singular {
                what: "genhexkins forward kinematics".into(),
                condition: f64::INFINITY,
            })?;
            t *= se3::exp(&step);
        }
        Err(KinError::NoConvergence {
            what: "genhexkins forward kinematics".into(),
            iterations: 50,
            residual: Vector6::from_fn(|i, _| self.inputs(&t)[i] - q[i]).norm(),
        })
    }

    /// The numbers as written.
    pub fn as_written(&self) -> Genhex {
        let r = |v: f64| -> f64 { fixed(v, DECIMALS).parse().expect("a formatted number parses") };
        Genhex {
            base: self.base.map(|p| p.map(r)),
            platform: self.platform.map(|p| p.map(r)),
            offset: self.offset.map(r),
        }
    }

    /// The file's text.
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        out.push_str("# LinuxCNC genhexkins parameters (HAL), written by kinecal\n");
        out.push_str("# (`kinecal model export MODEL --format linuxcnc-hexapod`; docs/controllers.md). Lengths in mm.\n");
        out.push_str("# base.N: strut N's base joint in the base (world) frame; platform.N: its platform joint in the\n");
        out.push_str("# platform frame. genhexkins's joint N is the strut length |p + R*platform.N - base.N|, with\n");
        out.push_str("# R = Rz(C)*Ry(B)*Rx(A).\n");
        for (name, pts) in [("base", &self.base), ("platform", &self.platform)] {
            for (i, p) in pts.iter().enumerate() {
                for (a, v) in ["x", "y", "z"].iter().zip(p) {
                    let _ = writeln!(out, "setp genhexkins.{name}.{i}.{a} {}", fixed(*v, DECIMALS));
                }
            }
        }
        out.push_str("# The actuator position (kinecal's input N) is the strut length plus offset.N.offset: LinuxCNC's\n");
        out.push_str("# `offset` component between joint N and its motor (loadrt offset count=6), or [JOINT_N] HOME_OFFSET\n");
        out.push_str("# shifted by it.\n");
        for (i, v) in self.offset.iter().enumerate() {
            let _ = writeln!(out, "setp offset.{i}.offset {}", fixed(*v, DECIMALS));
        }
        out
    }

    /// Read the file's text.
    pub fn parse(text: &str) -> Result<Genhex, ControllerError> {
        let err = |line: usize, message: String| ControllerError::Parse { line, message };
        let mut vals: [Option<f64>; 42] = [None; 42];
        let mut last = 0;
        for (k, raw) in text.lines().enumerate() {
            let n = k + 1;
            last = n;
            let line = strip_comment(raw).trim();
            if line.is_empty() {
                continue;
            }
            let words: Vec<&str> = line.split_whitespace().collect();
            let [cmd, name, value] = words.as_slice() else {
                return Err(err(n, format!("expected 'setp NAME VALUE', got '{line}'")));
            };
            if *cmd != "setp" {
                return Err(err(n, format!("expected 'setp NAME VALUE', got '{line}'")));
            }
            let parts: Vec<&str> = name.split('.').collect();
            let index = |s: &str| s.parse::<usize>().ok().filter(|i| *i < 6);
            let slot = match parts.as_slice() {
                ["genhexkins", which @ ("base" | "platform"), i, a @ ("x" | "y" | "z")] => index(i).map(|i| {
                    let axis = ["x", "y", "z"].iter().position(|s| s == a).unwrap_or(0);
                    (if *which == "base" { 0 } else { 18 }) + 3 * i + axis
                }),
                ["offset", i, "offset"] => index(i).map(|i| 36 + i),
                _ => None,
            };
            let Some(slot) = slot else {
                return Err(err(
                    n,
                    format!("unknown parameter '{name}' (expected genhexkins.base.N.x|y|z, genhexkins.platform.N.x|y|z or offset.N.offset, N = 0…5)"),
                ));
            };
            if vals[slot].is_some() {
                return Err(err(n, format!("'{name}' given twice")));
            }
            vals[slot] = Some(number(value, n, name)?);
        }
        let names = |s: usize| match s {
            0..=17 => format!("genhexkins.base.{}.{}", s / 3, ["x", "y", "z"][s % 3]),
            18..=35 => format!("genhexkins.platform.{}.{}", (s - 18) / 3, ["x", "y", "z"][s % 3]),
            _ => format!("offset.{}.offset", s - 36),
        };
        let mut v = [0.0; 42];
        for s in 0..42 {
            v[s] = vals[s].ok_or_else(|| err(last.max(1), format!("'{}' missing", names(s))))?;
        }
        Ok(Genhex {
            base: std::array::from_fn(|i| [v[3 * i], v[3 * i + 1], v[3 * i + 2]]),
            platform: std::array::from_fn(|i| [v[18 + 3 * i], v[19 + 3 * i], v[20 + 3 * i]]),
            offset: std::array::from_fn(|i| v[36 + i]),
        })
    }

    /// The Stewart platform of these parameters (see the module docs for its home and limits).
    pub fn stewart(&self) -> Result<crate::model::closed::ClosedLoop<Stewart>, ControllerError> {
        let mut theta = Vec::with_capacity(42);
        for i in 0..6 {
            theta.extend_from_slice(&self.platform[i]);
            theta.extend_from_slice(&self.base[i]);
            theta.push(-self.offset[i]);
        }
        let c = self.base.iter().fold(Vector3::zeros(), |s, b| s + Vector3::from(*b)) / 6.0;
        let reach = self.offset.iter().map(|o| -o).sum::<f64>() / 6.0;
        let start = Pose::translation(c.x, c.y, c.z + 0.9 * reach.abs());
        let home = self.forward(&[0.0; 6], &start)?;
        let r = se3::rpy(&home.rotation);
        let h = home.translation.vector;
        let home = [h.x, h.y, h.z, r[0], r[1], r[2]];
        let a = 8f64.to_radians();
        let ws = Workspace {
            min: [h.x - 40.0, h.y - 40.0, h.z - 40.0, r[0] - a, r[1] - a, r[2] - a],
            max: [h.x + 40.0, h.y + 40.0, h.z + 40.0, r[0] + a, r[1] + a, r[2] + a],
        };
        let system =
            Stewart::from_parameters(theta, home, [(-120.0, 120.0); 6], ws).map_err(|e| ControllerError::Unsupported(e.to_string()))?;
        Ok(Stewart::mechanism_of(system))
    }
}

/// Leg `i`'s two points and offset from (pose, input) samples: the linearised equations solved
/// exactly, then least squares on the strut lengths. Returns (base, platform, offset, max and
/// RMS strut-length residual).
/// One leg's fit: base point, platform point, offset, largest and RMS strut-length residual.
type LegFit = ([f64; 3], [f64; 3], f64, f64, f64);

fn fit_leg(samples: &[(Pose, f64)]) -> Result<LegFit, ControllerError> {
    // |R a + t − b|² = (q − o)²: |a|² + |t|² + |b|² − o² + 2 aᵀRᵀt − 2 bᵀt − 2 bᵀR a + 2 q o = q²,
    // linear in (c = |a|² + |b|² − o², a, b, M = b aᵀ, o).
    let mut a = DMatrix::zeros(samples.len(), 17);
    let mut y = DVector::zeros(samples.len());
    for (k, (t, q)) in samples.iter().enumerate() {
        let r = t.rotation.to_rotation_matrix().into_inner();
        let p = t.translation.vector;
        let rtp = r.transpose() * p;
        a[(k, 0)] = 1.0;
        for c in 0..3 {
            a[(k, 1 + c)] = 2.0 * rtp[c];
            a[(k, 4 + c)] = -2.0 * p[c];
            for d in 0..3 {
                a[(k, 7 + 3 * c + d)] = -2.0 * r[(c, d)];
            }
        }
        a[(k, 16)] = 2.0 * q;
        y[k] = q * q - p.norm_squared();
    }
    let sol = a
        .svd(true, true)
        .solve(&y, 1e-12)
        .map_err(|e| ControllerError::Unsupported(format!("leg fit: {e}")))?;
    let x0 = DVector::from_vec(vec![sol[1], sol[2], sol[3], sol[4], sol[5], sol[6], sol[16]]);
    let residual = |x: &DVector<f64>| -> Result<DVector<f64>, KinError> {
        Ok(DVector::from_iterator(
            samples.len(),
            samples.iter().map(|(t, q)| {
                let pa = t.transform_point(&Point3::new(x[0], x[1], x[2])).coords;
                (pa - Vector3::new(x[3], x[4], x[5])).norm() + x[6] - q
            }),
        ))
    };
    let (x, r) = least_squares(x0, 1e-6, 30, residual)?;
    let max = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let rms = (r.norm_squared() / r.len().max(1) as f64).sqrt();
    Ok(([x[3], x[4], x[5]], [x[0], x[1], x[2]], x[6], max, rms))
}

/// genhexkins's parameters of a model and the lines of what they do not represent.
pub fn from_model(file: &ModelFile) -> Result<(Genhex, Vec<String>, Option<f64>), ControllerError> {
    match &file.mechanism {
        MechanismSpec::Stewart(m) => {
            let theta = m.geometry();
            let tool = m.tool();
            let mut lost = Vec::new();
            if tool.iter().any(|v| *v != 0.0) {
                lost.push(format!(
                    "the model's tool offset ({}, {}, {}) mm in the platform frame (genhexkins controls the platform frame; tool-offset takes z only)",
                    fixed(tool[0], 6),
                    fixed(tool[1], 6),
                    fixed(tool[2], 6)
                ));
            }
            let leg = |i: usize| &theta[7 * i..7 * i + 7];
            let g = Genhex {
                base: std::array::from_fn(|i| [leg(i)[3], leg(i)[4], leg(i)[5]]),
                platform: std::array::from_fn(|i| [leg(i)[0], leg(i)[1], leg(i)[2]]),
                offset: std::array::from_fn(|i| -leg(i)[6]),
            };
            Ok((g, lost, None))
        }
        MechanismSpec::Limbs(_) => {
            let m = file.mechanism.build();
            if m.input_names().len() != 6 || m.task() != crate::model::Task::Full {
                return Err(ControllerError::Unsupported(format!(
                    "genhexkins describes six struts moving a platform in full pose; this machine has {} inputs and task {:?}",
                    m.input_names().len(),
                    m.task()
                )));
            }
            let configurations = spread_configurations(&*m, &file.mechanism.inputs(), 300, super::PROJECTION_SEED + 1)?;
            let poses = configurations.iter().map(|q| m.forward(q)).collect::<Result<Vec<_>, _>>()?;
            let (mut base, mut platform, mut offset) = ([[0.0; 3]; 6], [[0.0; 3]; 6], [0.0; 6]);
            let mut lost = Vec::new();
            let mut worst = 0.0f64;
            for i in 0..6 {
                let samples: Vec<(Pose, f64)> = poses.iter().zip(&configurations).map(|(t, q)| (*t, q[i])).collect();
                let (b, p, o, max, rms) = fit_leg(&samples)?;
                (base[i], platform[i], offset[i]) = (b, p, o);
                worst = worst.max(max);
                if max > 1e-9 {
                    lost.push(format!(
                        "strut {i} ({}): its limb is more than two joint points and a length (strut lengths off by up to {} mm, RMS {} mm)",
                        m.input_names()[i],
                        fixed(max, 9),
                        fixed(rms, 9)
                    ));
                }
            }
            Ok((Genhex { base, platform, offset }, lost, Some(worst)))
        }
        other => Err(ControllerError::Unsupported(format!(
            "a {} mechanism cannot be written as genhexkins parameters (a 6-UPS Stewart platform: kind \"stewart\" or six-legged \"limbs\")",
            other.kind()
        ))),
    }
}

/// The genhexkins HAL parameters of a Stewart platform (see the module docs) and what they leave.
pub fn export(file: &ModelFile) -> Result<Export, ControllerError> {
    let (g, not_represented, fit_residual_mm) = from_model(file)?;
    let text = g.to_text();
    let read = Genhex::parse(&text)?;
    let m = file.mechanism.build();
    let configurations = spread_configurations(&*m, &file.inputs(), super::PROJECTION_POSES, super::PROJECTION_SEED)?;
    let pairs = configurations
        .iter()
        .map(|q| {
            let t = m.forward(q)?;
            Ok((t, read.forward(q, &t)?))
        })
        .collect::<Result<Vec<_>, KinError>>()?;
    let mut not_written = Vec::new();
    if let Some(f) = &file.frames {
        let (a, b) = (f.measurement.translation.vector, f.tool.translation.vector);
        not_written.push(format!(
            "measurement frame (the base frame in the instrument's frame, at ({}, {}, {}) mm) — genhexkins's world is the base frame",
            fixed(a.x, 6),
            fixed(a.y, 6),
            fixed(a.z, 6)
        ));
        not_written.push(format!(
            "tool frame (the measured tool in the platform frame, at ({}, {}, {}) mm) — a tool offset, not kinematics",
            fixed(b.x, 6),
            fixed(b.y, 6),
            fixed(b.z, 6)
        ));
    }
    Ok(Export {
        text,
        projection: Projection {
            difference: PoseDifference::of(&pairs, true),
            not_represented,
            fit_residual_mm,
            not_written,
        },
    })
}

/// A Stewart model file of genhexkins parameters (see the module docs).
pub fn import(text: &str) -> Result<ModelFile, ControllerError> {
    let g = Genhex::parse(text)?;
    let mut file = ModelFile::new("hexapod", MechanismSpec::Stewart(g.stewart()?));
    file.description = Some(
        "imported from LinuxCNC genhexkins parameters (home at zero inputs; strokes ±120 mm and workspace ±40 mm, ±8° about it are not in the file)".into(),
    );
    Ok(file)
}
