//! Denavit–Hartenberg tables: standard DH and modified DH (Craig), built into local-POE chains
//! and recovered from them.
//!
//! # Conventions
//! A table has a base pose `B` (frame 0 in the world frame), one row per joint and a tool pose
//! `T` (the tool in the last DH frame). With joint value `q` (rad for revolute, mm for prismatic
//! joints; it adds to `θ` or to `d`):
//!
//! ```text
//! standard DH:  A_i(q) = Rz(θ_i + q)·Tz(d_i)·Tx(a_i)·Rx(α_i)·Ry(β_i)     (β: Hayati, 0 unless set)
//! modified DH:  A_i(q) = Rx(α_{i-1})·Tx(a_{i-1})·Rz(θ_i + q)·Tz(d_i)      (Craig; row i holds α_{i-1}, a_{i-1})
//! g(q) = B · A_1(q_1) ··· A_n(q_n) · T
//! ```
//!
//! # Into a local-POE chain ([`DhTable::to_chain`])
//! Joint `i` turns about (slides along) the z axis of the frame that precedes `Rz(q)` in its row,
//! so the chain is exact, with every joint twist a pure z rotation or translation:
//! standard `T_{0,1}(0) = B`, `T_{i,i+1}(0) = A_i(0)`, `T_{n,T}(0) = A_n(0)·T`; modified
//! `T_{0,1}(0) = B·A_1(0)`, `T_{i-1,i}(0) = A_i(0)`, `T_{n,T}(0) = T`. The chain has the usual
//! `6(n+1)` error parameters and the identifiability of any local-POE chain.
//!
//! # From a chain ([`DhTable::from_chain`])
//! The joint axes at zero joint values are lines in space; frame 0 is put on the first axis at
//! the foot of the world origin, with x the world x axis projected, and each next frame on the
//! common normal of two consecutive axes (θ, d, a, α), choosing among equivalent frames the one
//! whose x axis is closest to the previous frame's (so vendor tables with negative `a` come back
//! as written). The last frame is placed towards the tool; the tool pose takes the rest. Exactly
//! parallel axes (within 1e-13 rad) put the common normal through the previous frame (`d = 0`).
//!
//! Nearly parallel axes (as calibrated joints 2 and 3 of most arms are) have a common normal far
//! away along the axis: the table would be exact but `d` huge and ill-conditioned (Hayati 1983).
//! When it lies further than the arm's own size along the axis, standard DH may use Hayati's
//! `β` for that row (`d = 0`, a rotation about y) when asked ([`DhOptions::hayati`]); modified DH
//! has no such term here, and the conversion fails naming the joints ([`DhError`]).
use super::chain::{ChainJoint, JointKind, SerialChain};
use super::Mechanism;
use crate::se3::{self, Pose};
use nalgebra::{Translation3, UnitQuaternion, Vector3};
use thiserror::Error;

/// Which Denavit–Hartenberg convention a table follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DhConvention {
    /// Standard (distal) DH: `A_i = Rz(θ_i + q)·Tz(d_i)·Tx(a_i)·Rx(α_i)` (with Hayati's `·Ry(β_i)`).
    Standard,
    /// Modified (proximal) DH, Craig's: `A_i = Rx(α_{i-1})·Tx(a_{i-1})·Rz(θ_i + q)·Tz(d_i)`.
    Modified,
}

impl DhConvention {
    /// The table's key in a model file: `"dh"` or `"mdh"`.
    pub fn key(self) -> &'static str {
        match self {
            DhConvention::Standard => "dh",
            DhConvention::Modified => "mdh",
        }
    }
}

/// One row of a DH table (mm and rad).
#[derive(Debug, Clone, PartialEq)]
pub struct DhJoint {
    /// Joint name (the input name).
    pub name: String,
    /// Revolute (`q` adds to θ) or prismatic (`q` adds to d).
    pub kind: JointKind,
    /// Link length `a` (mm); in modified DH `a_{i-1}`.
    pub a: f64,
    /// Link twist `α` (rad); in modified DH `α_{i-1}`.
    pub alpha: f64,
    /// Link offset `d` (mm) at zero joint value.
    pub d: f64,
    /// Joint angle `θ` (rad) at zero joint value.
    pub theta: f64,
    /// Hayati's rotation about y (rad), standard DH only; 0 in a plain table.
    pub beta: f64,
    /// Joint limits (rad or mm), if any.
    pub limits: Option<(f64, f64)>,
}

/// A DH table with its base and tool poses (mm and rad).
#[derive(Debug, Clone, PartialEq)]
pub struct DhTable {
    /// Standard or modified.
    pub convention: DhConvention,
    /// Frame 0 in the world frame.
    pub base: Pose,
    /// One row per joint.
    pub joints: Vec<DhJoint>,
    /// The tool in the last DH frame.
    pub tool: Pose,
}

/// Why a chain has no (useful) DH table.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum DhError {
    /// Consecutive joint axes that are nearly, but not exactly, parallel.
    #[error("{}: {}", pairs.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("; "), advice(*convention))]
    NearlyParallel {
        /// The convention asked for.
        convention: DhConvention,
        /// Every pair that does not fit.
        pairs: Vec<NearlyParallel>,
    },
    /// The chain has a joint twist that is neither a pure rotation nor a pure translation.
    #[error("joint '{0}' is a screw joint (its twist has both a rotation and a translation): DH has no such joint")]
    Screw(String),
    /// The model is not a serial chain.
    #[error("{0} cannot be written as a DH table: only plain serial chains can")]
    NotSerial(String),
    /// The file text could not be written.
    #[error("{0}")]
    Write(String),
    /// The rebuilt table does not reproduce the chain (a bug, reported rather than written).
    #[error("the DH table does not reproduce the model: {0:.3e} mm apart")]
    Mismatch(f64),
}

fn advice(convention: DhConvention) -> &'static str {
    match convention {
        DhConvention::Standard => {
            "standard DH puts their common normal beyond the arm; export with Hayati's β for these rows (--hayati), or keep the model file / URDF, which hold any geometry"
        }
        DhConvention::Modified => {
            "modified DH puts their common normal beyond the arm and has no Hayati β here; use standard DH with --hayati, or keep the model file / URDF, which hold any geometry"
        }
    }
}

/// Two consecutive joint axes that are nearly parallel: what standard or modified DH cannot
/// hold without a huge, ill-conditioned `d`.
#[derive(Debug, Clone, PartialEq)]
pub struct NearlyParallel {
    /// The first joint's name.
    pub first: String,
    /// The second joint's name.
    pub second: String,
    /// Angle between the axes (rad).
    pub angle: f64,
    /// Where their common normal meets the first axis, from the previous frame (mm).
    pub offset: f64,
}

impl std::fmt::Display for NearlyParallel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "joints {} and {} have axes {:.4}° from parallel, common normal {:.0} mm along the axis",
            self.first,
            self.second,
            self.angle.to_degrees(),
            self.offset
        )
    }
}

/// Options of [`DhTable::from_chain`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DhOptions {
    /// Standard DH only: use Hayati's β (and `d = 0`) for rows whose next axis is nearly
    /// parallel, instead of failing.
    pub hayati: bool,
}

fn rz(t: f64) -> Pose {
    Pose::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::z_axis(), t))
}
fn rx(t: f64) -> Pose {
    Pose::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::x_axis(), t))
}
fn ry(t: f64) -> Pose {
    Pose::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(&Vector3::y_axis(), t))
}

impl DhJoint {
    /// The row's transform at joint value `q` in `convention`.
    pub fn transform(&self, convention: DhConvention, q: f64) -> Pose {
        let (dt, dd) = match self.kind {
            JointKind::Revolute => (q, 0.0),
            JointKind::Prismatic => (0.0, q),
        };
        match convention {
            DhConvention::Standard => rz(self.theta + dt) * se3::translation(self.a, 0.0, self.d + dd) * rx(self.alpha) * ry(self.beta),
            DhConvention::Modified => {
                rx(self.alpha) * se3::translation(self.a, 0.0, 0.0) * rz(self.theta + dt) * se3::translation(0.0, 0.0, self.d + dd)
            }
        }
    }
}

impl DhTable {
    /// Tool pose at joint values `q` straight from the table (the formula of the module docs;
    /// [`DhTable::to_chain`] gives the same through the local-POE chain).
    pub fn forward(&self, q: &[f64]) -> Pose {
        let mut g = self.base;
        for (j, qi) in self.joints.iter().zip(q) {
            g *= j.transform(self.convention, *qi);
        }
        g * self.tool
    }

    /// The local-POE chain of this table (see the module docs), named `name`.
    pub fn to_chain(&self, name: &str) -> SerialChain {
        let joints: Vec<ChainJoint> = self
            .joints
            .iter()
            .map(|j| {
                let mut c = match j.kind {
                    JointKind::Revolute => ChainJoint::revolute(j.name.clone(), Vector3::z()),
                    JointKind::Prismatic => ChainJoint::prismatic(j.name.clone(), Vector3::z()),
                };
                c.limits = j.limits;
                c
            })
            .collect();
        let at_zero: Vec<Pose> = self.joints.iter().map(|j| j.transform(self.convention, 0.0)).collect();
        let n = at_zero.len();
        let (initial, tool) = match self.convention {
            DhConvention::Standard => {
                let mut initial = vec![self.base];
                initial.extend(at_zero[..n.saturating_sub(1)].iter().copied());
                let last = at_zero.last().copied().unwrap_or_else(Pose::identity);
                (initial, last * self.tool)
            }
            DhConvention::Modified => {
                let mut initial = at_zero.clone();
                if let Some(first) = initial.first_mut() {
                    *first = self.base * *first;
                }
                (initial, self.tool)
            }
        };
        SerialChain::new(name, joints, initial, tool)
    }

    /// The table of `chain` in `convention` (see the module docs). Fails when consecutive axes
    /// are nearly parallel (unless standard DH with [`DhOptions::hayati`]) or a joint is a
    /// screw; the table is checked against the chain at 100 configurations before it is returned.
    pub fn from_chain(chain: &SerialChain, convention: DhConvention, opts: DhOptions) -> Result<DhTable, DhError> {
        let lines = axis_lines(chain)?;
        let n = lines.len();
        let tool_world = chain.forward(&vec![0.0; n]).map_err(|_| DhError::Mismatch(f64::NAN))?;
        // The arm's size: a common normal further than this along an axis marks Hayati's case.
        let mut reach = 0.0;
        let mut prev = lines.first().map_or(Vector3::zeros(), |l| l.point);
        for l in lines.iter().skip(1) {
            reach += (l.point - prev).norm();
            prev = l.point;
        }
        reach += (tool_world.translation.vector - prev).norm();
        let limit = reach.max(1.0);

        let first = &lines[0];
        let z0 = first.dir;
        let o0 = first.point - first.point.dot(&z0) * z0;
        let x0 = perpendicular_hint(&z0, &[Vector3::x(), Vector3::y()]);
        let base = frame(&x0, &z0, &o0);
        let mut f = base;
        let mut rows = Vec::with_capacity(n);
        let mut bad = Vec::new();
        // Modified DH: the (a, α) that the next row carries.
        let mut pending = (0.0, 0.0);
        for i in 0..n {
            let joint = &chain.joints()[i];
            if convention == DhConvention::Modified {
                f *= rx(pending.1) * se3::translation(pending.0, 0.0, 0.0);
            }
            let (o, z, x_prev) = parts(&f);
            let step = if i + 1 < n {
                let next = &lines[i + 1];
                let s = common_normal(&o, &z, &x_prev, &next.point, &next.dir);
                if s.nearly_parallel && s.d.abs() > limit {
                    let hayati = convention == DhConvention::Standard && opts.hayati;
                    if hayati {
                        hayati_step(&o, &z, &x_prev, &next.point, &next.dir)
                    } else {
                        bad.push(NearlyParallel {
                            first: joint.name.clone(),
                            second: chain.joints()[i + 1].name.clone(),
                            angle: z.cross(&next.dir).norm().asin(),
                            offset: s.d,
                        });
                        s
                    }
                } else {
                    s
                }
            } else {
                towards_tool(&o, &z, &x_prev, &tool_world, convention)
            };
            let row = DhJoint {
                name: joint.name.clone(),
                kind: joint.kind,
                a: if convention == DhConvention::Standard { step.a } else { pending.0 },
                alpha: if convention == DhConvention::Standard {
                    step.alpha
                } else {
                    pending.1
                },
                d: step.d,
                theta: step.theta,
                beta: step.beta,
                limits: joint.limits,
            };
            match convention {
                DhConvention::Standard => f *= row.transform(convention, 0.0),
                DhConvention::Modified => {
                    f *= rz(step.theta) * se3::translation(0.0, 0.0, step.d);
                    pending = (step.a, step.alpha);
                }
            }
            rows.push(row);
        }
        if !bad.is_empty() {
            return Err(DhError::NearlyParallel { convention, pairs: bad });
        }
        let table = DhTable {
            convention,
            base,
            joints: rows,
            tool: f.inverse() * tool_world,
        };
        let rebuilt = table.to_chain(chain.name());
        let mut worst: f64 = 0.0;
        for k in 0..100 {
            let q: Vec<f64> = (0..n).map(|j| ((k * 13 + j * 7) as f64 * 0.61).sin() * 2.5).collect();
            let (a, b) = (chain.forward(&q), rebuilt.forward(&q));
            if let (Ok(a), Ok(b)) = (a, b) {
                let e = se3::pose_error(&a, &b);
                worst = worst.max(se3::lin(&e).norm() + 1e3 * se3::ang(&e).norm());
            }
        }
        if worst.is_nan() || worst > 1e-6 {
            return Err(DhError::Mismatch(worst));
        }
        Ok(table)
    }
}

/// A joint axis at zero joint values, in the world frame: a point and a unit direction.
struct AxisLine {
    point: Vector3<f64>,
    dir: Vector3<f64>,
}

fn axis_lines(chain: &SerialChain) -> Result<Vec<AxisLine>, DhError> {
    let mut g = Pose::identity();
    let mut out = Vec::with_capacity(chain.n_joints());
    for (j, joint) in chain.joints().iter().enumerate() {
        g *= chain.initial_poses()[j];
        let s = joint.twist();
        let (v, w) = (se3::lin(&s), se3::ang(&s));
        let (local_point, local_dir) = match joint.kind {
            JointKind::Revolute => {
                if w.norm() < 1e-12 {
                    return Err(DhError::Screw(joint.name.clone()));
                }
                if v.dot(&w).abs() > 1e-12 * w.norm() * (1.0 + v.norm()) {
                    return Err(DhError::Screw(joint.name.clone()));
                }
                (w.cross(&v) / w.norm_squared(), w.normalize())
            }
            JointKind::Prismatic => {
                if w.norm() > 1e-12 || v.norm() < 1e-12 {
                    return Err(DhError::Screw(joint.name.clone()));
                }
                (Vector3::zeros(), v.normalize())
            }
        };
        out.push(AxisLine {
            point: (g * nalgebra::Point3::from(local_point)).coords,
            dir: g.rotation * local_dir,
        });
    }
    Ok(out)
}

/// The first of `hints` not (nearly) along `z`, projected perpendicular to `z`, unit length.
fn perpendicular_hint(z: &Vector3<f64>, hints: &[Vector3<f64>]) -> Vector3<f64> {
    for h in hints {
        let p = h - h.dot(z) * z;
        if p.norm() > 1e-6 {
            return p.normalize();
        }
    }
    let any = if z.x.abs() < 0.9 { Vector3::x() } else { Vector3::y() };
    (any - any.dot(z) * z).normalize()
}

fn frame(x: &Vector3<f64>, z: &Vector3<f64>, o: &Vector3<f64>) -> Pose {
    let y = z.cross(x);
    let r = nalgebra::Matrix3::from_columns(&[*x, y, *z]);
    se3::pose_from_matrix(&r, o)
}

fn parts(f: &Pose) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
    (f.translation.vector, f.rotation * Vector3::z(), f.rotation * Vector3::x())
}

/// One step from a frame on axis i (origin `o`, z along the axis, x `x_prev`) to the next.
struct Step {
    theta: f64,
    d: f64,
    a: f64,
    alpha: f64,
    beta: f64,
    nearly_parallel: bool,
}

/// Angle about `z` from `from` to `to` (both perpendicular to `z`).
fn angle_about(z: &Vector3<f64>, from: &Vector3<f64>, to: &Vector3<f64>) -> f64 {
    from.cross(to).dot(z).atan2(from.dot(to))
}

/// `x` along `r` (signed length `a`), flipped when that keeps it closer to `x_prev`.
fn signed_x(r: &Vector3<f64>, x_prev: &Vector3<f64>, fallback: &Vector3<f64>) -> (Vector3<f64>, f64) {
    let len = r.norm();
    if len <= 1e-10 {
        let x = if fallback.dot(x_prev) < 0.0 { -fallback } else { *fallback };
        return (x, 0.0);
    }
    let x = r / len;
    if x.dot(x_prev) < -1e-9 {
        (-x, -len)
    } else {
        (x, len)
    }
}

/// θ, d, a, α from axis (o, z) to the line (p, u) along their common normal.
fn common_normal(o: &Vector3<f64>, z: &Vector3<f64>, x_prev: &Vector3<f64>, p: &Vector3<f64>, u: &Vector3<f64>) -> Step {
    let c = z.cross(u);
    let s = c.norm();
    let (x, d, a, nearly_parallel) = if s <= 1e-13 {
        let w = p - o;
        let r = w - w.dot(z) * z;
        let (x, a) = signed_x(&r, x_prev, x_prev);
        (x, 0.0, a, false)
    } else {
        let w0 = o - p;
        let b = z.dot(u);
        let (d1, e) = (z.dot(&w0), u.dot(&w0));
        let den = 1.0 - b * b;
        let t1 = (b * e - d1) / den;
        let t2 = (e - b * d1) / den;
        let foot1 = o + t1 * z;
        let foot2 = p + t2 * u;
        let (x, a) = signed_x(&(foot2 - foot1), x_prev, &(c / s));
        (x, t1, a, s < 0.1)
    };
    Step {
        theta: angle_about(z, x_prev, &x),
        d,
        a,
        alpha: angle_about(&x, z, u),
        beta: 0.0,
        nearly_parallel,
    }
}

/// Hayati's step (standard DH, nearly parallel axes): `d = 0`, the next frame where the next
/// axis crosses the plane through `o` perpendicular to `z`, `α` and `β` turning `z` onto `u`.
fn hayati_step(o: &Vector3<f64>, z: &Vector3<f64>, x_prev: &Vector3<f64>, p: &Vector3<f64>, u: &Vector3<f64>) -> Step {
    let t = z.dot(&(o - p)) / z.dot(u);
    let hit = p + t * u;
    let (x, a) = signed_x(&(hit - o), x_prev, x_prev);
    let y = z.cross(&x);
    let beta = u.dot(&x).clamp(-1.0, 1.0).asin();
    let alpha = (-u.dot(&y)).atan2(u.dot(z));
    Step {
        theta: angle_about(z, x_prev, &x),
        d: 0.0,
        a,
        alpha,
        beta,
        nearly_parallel: true,
    }
}

/// The last row: along the last axis to the tool's foot, x towards the tool origin (or along the
/// tool's x axis when the tool sits on the axis), α turning z onto the tool's z when that is a
/// rotation about x (standard DH only; modified DH has no α after the last joint).
fn towards_tool(o: &Vector3<f64>, z: &Vector3<f64>, x_prev: &Vector3<f64>, tool: &Pose, convention: DhConvention) -> Step {
    let w = tool.translation.vector - o;
    let d = w.dot(z);
    let r = w - d * z;
    let (tx, tz) = (tool.rotation * Vector3::x(), tool.rotation * Vector3::z());
    let hint = perpendicular_hint(z, &[tx, tool.rotation * Vector3::y(), *x_prev]);
    let (x, a) = match convention {
        DhConvention::Standard => signed_x(&r, x_prev, &hint),
        DhConvention::Modified => (hint, 0.0),
    };
    let alpha = if convention == DhConvention::Standard && tz.dot(&x).abs() < 1e-12 {
        angle_about(&x, z, &tz)
    } else {
        0.0
    };
    Step {
        theta: angle_about(z, x_prev, &x),
        d,
        a,
        alpha,
        beta: 0.0,
        nearly_parallel: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn ur5e(convention: DhConvention) -> DhTable {
        let a = [0.0, -425.0, -392.2, 0.0, 0.0, 0.0];
        let d = [162.5, 0.0, 0.0, 133.3, 99.7, 99.6];
        let alpha = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];
        assert_eq!(convention, DhConvention::Standard);
        DhTable {
            convention,
            base: Pose::identity(),
            joints: (0..6)
                .map(|i| DhJoint {
                    name: format!("q{}", i + 1),
                    kind: JointKind::Revolute,
                    a: a[i],
                    alpha: alpha[i],
                    d: d[i],
                    theta: 0.0,
                    beta: 0.0,
                    limits: None,
                })
                .collect(),
            tool: Pose::identity(),
        }
    }

    #[test]
    fn chain_equals_table_and_table_comes_back() {
        let t = ur5e(DhConvention::Standard);
        let c = t.to_chain("ur5e");
        let q = [0.3, -1.2, 0.8, 2.0, -0.4, 1.1];
        let e = se3::pose_error(&t.forward(&q), &c.forward(&q).unwrap());
        assert!(e.norm() < 1e-12, "{e}");
        let back = DhTable::from_chain(&c, DhConvention::Standard, DhOptions::default()).unwrap();
        for (r, s) in back.joints.iter().zip(&t.joints) {
            assert!((r.a - s.a).abs() < 1e-9 && (r.d - s.d).abs() < 1e-9, "{r:?} vs {s:?}");
            assert!((r.alpha - s.alpha).abs() < 1e-12 && r.theta.abs() < 1e-12, "{r:?} vs {s:?}");
        }
        assert!(se3::log(&back.tool).norm() < 1e-9 && se3::log(&back.base).norm() < 1e-12);
    }
}
