//! Klipper linear delta: `printer.cfg`'s `[printer] kinematics: delta` with `delta_radius`, and
//! per tower `[stepper_a|b|c]` `angle`, `arm_length` and `position_endstop`.
//!
//! # Convention (Klipper's `delta.py`)
//! Tower `i` stands at `(R·cos θ_i, R·sin θ_i)` (`R` = `delta_radius`, the effective radius:
//! rod pivots and effector offsets folded in; `θ_i` = `angle`, degrees, written in [0°, 360°));
//! its carriage at height `h_i` holds a rod of `arm_length L_i` whose other end is the nozzle:
//! `|p − (R cos θ_i, R sin θ_i, h_i)| = L_i`, the nozzle below the carriages. Homing puts
//! carriage `i` at `h_i = position_endstop_i + √(L_i² − R²)`. mm; z = 0 is the bed.
//!
//! kinecal's inputs `c1, c2, c3` (in the model's order) are towers a, b, c; an input is the
//! carriage height Klipper reports for the printer as it was configured when the data were
//! taken, and the input's upper limit is the carriage height at the endstop (a model imported
//! from `printer.cfg` has exactly that). The written file then homes each carriage where the
//! calibrated model puts it.
//!
//! # Export ([`export`])
//! A `kind = "limbs"` machine with three inputs and a position task. Least squares over
//! configurations spread over the workspace: per tower, the tower position, arm length and
//! carriage offset that best reproduce the model's inputs from the nozzle positions (exact
//! solution of the squared equations), the circle through the three towers (its centre is
//! Klipper's origin: `(x0, y0)` in the model's base frame, reported), then Gauss–Newton on the
//! nozzle positions. Rail tilts, parallelogram and joint-axis errors have no Klipper parameter:
//! reported with their residual, and each rail's lean from Klipper's z. Values with 10 decimals
//! (mm, degrees).
//!
//! # On a printer's bed ([`export_with`], [`KlipperOptions`])
//! A printer calibrated from its probe's touches on the bed (and a few ballbar lengths) is known
//! only up to a rigid motion. Given the bed ([`super::bed::bed_from_touches`]), Klipper's frame
//! is the bed's: `z = 0` on it, `z` along its normal, the origin below the towers' circle
//! centre, the nozzle the model's tool point (its `[frames]` included); tower c's angle may be
//! given (the turn about the normal nothing measured fixes). What Klipper cannot represent —
//! rails leaning from the bed's normal, the rest of the geometry — is printed, each rail's lean
//! in Klipper's frame.
//!
//! # Import ([`import`])
//! A limbs model of the effective geometry: prismatic carriages along z at the towers, a rod
//! with a universal joint at each end, all rods meeting at the nozzle; carriage limits 0 to the
//! endstop height, workspace ±0.35 R in x and y and 5–50 % of the mean `position_endstop` in z
//! (not in the file: edit the model file).
use super::{fixed, number, strip_comment, ControllerError, Export, Projection};
use crate::error::KinError;
use crate::io::model_file::{MechanismSpec, ModelFile};
use crate::model::projection::{least_squares, spread_configurations, unrepresented_positions, PoseDifference};
use crate::model::Mechanism;
use crate::se3::Pose;
use nalgebra::{DMatrix, DVector, Vector3};
use std::fmt::Write as _;
use std::path::Path;

const DECIMALS: usize = 10;
const TOWERS: [&str; 3] = ["a", "b", "c"];

/// Klipper's delta parameters (mm, degrees).
#[derive(Debug, Clone, PartialEq)]
pub struct KlipperDelta {
    /// `delta_radius`.
    pub radius: f64,
    /// `angle` of towers a, b, c (degrees).
    pub angle: [f64; 3],
    /// `arm_length` of towers a, b, c.
    pub arm_length: [f64; 3],
    /// `position_endstop` of towers a, b, c.
    pub position_endstop: [f64; 3],
}

impl KlipperDelta {
    /// Tower `i`'s xy position.
    pub fn tower(&self, i: usize) -> Vector3<f64> {
        let a = self.angle[i].to_radians();
        Vector3::new(self.radius * a.cos(), self.radius * a.sin(), 0.0)
    }

    /// Carriage height at the endstop.
    pub fn endstop_height(&self, i: usize) -> f64 {
        self.position_endstop[i] + (self.arm_length[i].powi(2) - self.radius.powi(2)).sqrt()
    }

    /// The nozzle at carriage heights `h` (Klipper's frame).
    pub fn forward(&self, h: &[f64]) -> Result<Vector3<f64>, KinError> {
        let p: [Vector3<f64>; 3] = std::array::from_fn(|i| self.tower(i) + Vector3::new(0.0, 0.0, h[i]));
        trilaterate(&p, &self.arm_length)
    }

    /// The numbers as written.
    pub fn as_written(&self) -> KlipperDelta {
        let r = |v: f64| -> f64 { fixed(v, DECIMALS).parse().expect("a formatted number parses") };
        KlipperDelta {
            radius: r(self.radius),
            angle: self.angle.map(|a| angle_text(a).parse().expect("a formatted number parses")),
            arm_length: self.arm_length.map(r),
            position_endstop: self.position_endstop.map(r),
        }
    }

    /// The file's text (the `printer.cfg` sections).
    pub fn to_text(&self) -> String {
        let mut out = String::new();
        out.push_str("# Klipper linear delta kinematics, written by kinecal\n");
        out.push_str("# (`kinecal model export MODEL --format klipper-delta`; docs/controllers.md). Merge these keys\n");
        out.push_str("# into printer.cfg. mm and degrees; tower i at (delta_radius*cos(angle), delta_radius*sin(angle));\n");
        out.push_str("# z = 0 is the bed: the model's base plane, or the bed given to the export (--bed).\n");
        out.push_str("[printer]\nkinematics: delta\n");
        let _ = writeln!(out, "delta_radius: {}", fixed(self.radius, DECIMALS));
        for (i, t) in TOWERS.iter().enumerate() {
            let _ = writeln!(out, "\n[stepper_{t}]");
            let _ = writeln!(out, "angle: {}", angle_text(self.angle[i]));
            let _ = writeln!(out, "arm_length: {}", fixed(self.arm_length[i], DECIMALS));
            let _ = writeln!(out, "position_endstop: {}", fixed(self.position_endstop[i], DECIMALS));
        }
        out
    }

    /// Read a `printer.cfg` (other sections and keys are ignored; Klipper's defaults apply: towers
    /// b and c take a's arm length and endstop, angles 210°, 330°, 90°).
    pub fn parse(text: &str) -> Result<KlipperDelta, ControllerError> {
        let err = |line: usize, message: String| ControllerError::Parse { line, message };
        let mut section = String::new();
        let (mut kinematics, mut radius) = (None, None);
        let mut angle = [None; 3];
        let mut arm = [None; 3];
        let mut endstop = [None; 3];
        let mut last = 0;
        for (k, raw) in text.lines().enumerate() {
            let n = k + 1;
            last = n;
            let line = strip_comment(raw.split(';').next().unwrap_or("")).trim();
            if line.is_empty() {
                continue;
            }
            if let Some(rest) = line.strip_prefix('[') {
                let Some(name) = rest.strip_suffix(']') else {
                    return Err(err(n, format!("a section header ends with ']': '{line}'")));
                };
                section = name.trim().to_string();
                continue;
            }
            let Some((key, value)) = line.split_once([':', '=']) else {
                return Err(err(n, format!("expected 'key: value', got '{line}'")));
            };
            let (key, value) = (key.trim(), value.trim());
            let tower = section.strip_prefix("stepper_").and_then(|t| TOWERS.iter().position(|x| *x == t));
            let set = |slot: &mut Option<(f64, usize)>, what: &str| -> Result<(), ControllerError> {
                if slot.is_some() {
                    return Err(err(n, format!("'{what}' given twice in [{section}]")));
                }
                *slot = Some((number(value, n, &format!("[{section}] {key}"))?, n));
                Ok(())
            };
            match (section.as_str(), tower, key) {
                ("printer", _, "kinematics") => kinematics = Some((value.to_string(), n)),
                ("printer", _, "delta_radius") => set(&mut radius, key)?,
                (_, Some(t), "angle") => set(&mut angle[t], key)?,
                (_, Some(t), "arm_length") => set(&mut arm[t], key)?,
                (_, Some(t), "position_endstop") => set(&mut endstop[t], key)?,
                _ => {}
            }
        }
        let end = last.max(1);
        match kinematics {
            Some((k, _)) if k == "delta" => {}
            Some((k, line)) => return Err(err(line, format!("kinematics: {k} — only 'delta' is a linear delta"))),
            None => return Err(err(end, "no [printer] 'kinematics: delta'".into())),
        }
        let (radius, rline) = radius.ok_or_else(|| err(end, "no [printer] delta_radius".into()))?;
        if radius <= 0.0 {
            return Err(err(rline, format!("delta_radius must be positive, got {radius}")));
        }
        let first = |v: &[Option<(f64, usize)>; 3], what: &str| -> Result<[(f64, usize); 3], ControllerError> {
            let a = v[0].ok_or_else(|| err(end, format!("no [stepper_a] {what}")))?;
            Ok([a, v[1].unwrap_or(a), v[2].unwrap_or(a)])
        };
        let arm = first(&arm, "arm_length")?;
        let endstop = first(&endstop, "position_endstop")?;
        let defaults = [210.0, 330.0, 90.0];
        for (l, line) in arm {
            if l <= radius {
                return Err(err(line, format!("arm_length {l} must exceed delta_radius {radius}")));
            }
        }
        Ok(KlipperDelta {
            radius,
            angle: std::array::from_fn(|i| angle[i].map(|(v, _)| v).unwrap_or(defaults[i])),
            arm_length: arm.map(|(v, _)| v),
            position_endstop: endstop.map(|(v, _)| v),
        })
    }

    /// The limbs model of these parameters (see the module docs).
    pub fn model_file(&self) -> Result<ModelFile, ControllerError> {
        let pe = self.position_endstop.iter().sum::<f64>() / 3.0;
        let (zlo, zhi) = (0.05 * pe, 0.5 * pe);
        let zh = 0.5 * (zlo + zhi);
        let w = 0.35 * self.radius;
        let mut t = String::new();
        let _ = writeln!(
            t,
            "name = \"klipper-delta\"\ndescription = \"linear delta imported from Klipper printer.cfg (effective geometry)\"\n"
        );
        let _ = writeln!(
            t,
            "[units]\nlength = \"mm\"\nangle = \"deg\"\n\n[mechanism]\nkind = \"limbs\"\ntask = \"position\"\n"
        );
        let _ = writeln!(t, "[mechanism.home]\nposition = [0.0, 0.0, {zh:?}]\nrpy = [0.0, 0.0, 0.0]\n");
        let _ = writeln!(
            t,
            "[mechanism.workspace]\nposition_min = [{:?}, {:?}, {zlo:?}]\nposition_max = [{w:?}, {w:?}, {zhi:?}]\n",
            -w, -w
        );
        for i in 0..3 {
            let p = self.tower(i);
            let s = (self.arm_length[i].powi(2) - self.radius.powi(2)).sqrt();
            let alpha = (-self.radius).atan2(-s).to_degrees();
            let _ = writeln!(t, "[[mechanism.limbs]]\nname = \"arm{}\"\nend = \"frame\"\n", i + 1);
            let _ = writeln!(
                t,
                "[[mechanism.limbs.joints]]\nname = \"c{}\"\ntype = \"prismatic\"\nrole = \"actuated\"\naxis = [0.0, 0.0, 1.0]\nlimits = [0.0, {:?}]\nhome = {:?}\nposition = [{:?}, {:?}, 0.0]\nrpy = [0.0, 0.0, {:?}]\n",
                i + 1,
                self.endstop_height(i),
                zh + s,
                p.x,
                p.y,
                self.angle[i]
            );
            let _ = writeln!(
                t,
                "[[mechanism.limbs.joints]]\nname = \"uc{}\"\ntype = \"universal\"\nrole = \"passive\"\naxes = [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]\nhome = [{alpha:?}, 0.0]\n",
                i + 1
            );
            let _ = writeln!(
                t,
                "[[mechanism.limbs.joints]]\nname = \"up{}\"\ntype = \"universal\"\nrole = \"passive\"\naxes = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]\nhome = [0.0, {:?}]\nposition = [0.0, 0.0, {:?}]\n",
                i + 1,
                -alpha,
                self.arm_length[i]
            );
        }
        t.push_str("[calibration]\nfree = [\"*\"]\nfixed = [\"arm*.1-2.v*\", \"arm*.1-2.wy\", \"arm*.1-2.wz\", \"arm*.3-4.vx\", \"arm*.3-4.vy\", \"arm*.3-4.wx\", \"arm*.5-T.*\"]\n");
        ModelFile::load_str(Path::new("klipper-delta"), &t)
            .map_err(|e| ControllerError::Unsupported(format!("the imported delta does not assemble: {e}")))
    }
}

/// The point at distances `l` from `p` (three sphere centres), the lower of the two.
pub fn trilaterate(p: &[Vector3<f64>; 3], l: &[f64; 3]) -> Result<Vector3<f64>, KinError> {
    let d21 = p[1] - p[0];
    let d = d21.norm();
    let ex = d21 / d;
    let i = ex.dot(&(p[2] - p[0]));
    let ey_raw = p[2] - p[0] - i * ex;
    let j = ey_raw.norm();
    let ey = ey_raw / j;
    let mut ez = ex.cross(&ey);
    if ez.z > 0.0 {
        ez = -ez;
    }
    let x = (l[0] * l[0] - l[1] * l[1] + d * d) / (2.0 * d);
    let y = (l[0] * l[0] - l[2] * l[2] + i * i + j * j) / (2.0 * j) - i / j * x;
    let z2 = l[0] * l[0] - x * x - y * y;
    if z2 < 0.0 || !z2.is_finite() {
        return Err(KinError::Unreachable("the three rods do not meet".into()));
    }
    Ok(p[0] + x * ex + y * ey + z2.sqrt() * ez)
}

/// The delta's Klipper parameters, its origin `(x0, y0)` in the model's base frame, and per
/// tower the carriage offset (Klipper height − model input). Parameters `x`: R, θ (rad) ×3,
/// L ×3, offset ×3, x0, y0.
fn unpack(x: &DVector<f64>, upper: &[f64; 3]) -> (KlipperDelta, [f64; 3], [f64; 2]) {
    let off = [x[7], x[8], x[9]];
    let mut k = KlipperDelta {
        radius: x[0],
        angle: [x[1].to_degrees(), x[2].to_degrees(), x[3].to_degrees()],
        arm_length: [x[4], x[5], x[6]],
        position_endstop: [0.0; 3],
    };
    for i in 0..3 {
        let s = (k.arm_length[i].powi(2) - k.radius.powi(2)).sqrt();
        k.position_endstop[i] = upper[i] + off[i] - s;
    }
    (k, off, [x[10], x[11]])
}

/// Each carriage input's upper limit: its value at the endstop.
fn endstop_inputs(inputs: &[crate::model::kind::InputSpec]) -> Result<[f64; 3], ControllerError> {
    let mut out = [0.0; 3];
    for (o, i) in out.iter_mut().zip(inputs) {
        *o = i.limits.map(|(_, hi)| hi).ok_or_else(|| {
            ControllerError::Unsupported(format!(
                "carriage input '{}' has no limits: its upper limit is taken as its value at the endstop (give it limits in the model file)",
                i.name
            ))
        })?;
    }
    Ok(out)
}

/// A tower angle as written: degrees in [0, 360).
fn angle_text(a: f64) -> String {
    let s = fixed(a.rem_euclid(360.0), DECIMALS);
    if s == fixed(360.0, DECIMALS) {
        fixed(0.0, DECIMALS)
    } else {
        s
    }
}

/// Where Klipper's frame stands ([`from_model`], [`export_with`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct KlipperOptions {
    /// The printer's bed in the model's frame (e.g. [`super::bed::bed_from_touches`]): Klipper's
    /// `z = 0` on it, `z` along its normal, and the nozzle the model's tool point (its
    /// `[frames]` included). Without one, Klipper's `z` is the model's base `z` and the nozzle
    /// the mechanism's platform origin.
    pub bed: Option<super::bed::Bed>,
    /// Tower c's `angle` (degrees): the frame turned about its `z` so that tower c stands there
    /// (what nothing measured fixes; Klipper's delta calibration keeps it too). Without one, `x`
    /// is the model's `x` (projected onto the bed).
    pub angle_c: Option<f64>,
}

/// Klipper's parameters of a linear delta model and what they leave.
#[derive(Debug, Clone, PartialEq)]
pub struct KlipperFit {
    /// The parameters (not rounded).
    pub delta: KlipperDelta,
    /// Klipper's frame in the model's frame: a nozzle at `k` in Klipper's frame is at
    /// `frame · k` in the model's.
    pub frame: Pose,
    /// The largest nozzle-position residual of the fit (mm).
    pub fit_residual_mm: f64,
    /// What Klipper cannot represent, each a line.
    pub lost: Vec<String>,
}

/// Tower `i`'s rail direction in the frame of `points` from the nozzle positions and its
/// carriage input `c`: `|p − a − d·c|² = L²` is linear in `a`, `d`, `a·d` and `|a|² − L²`
/// when `|d| = 1` (least squares; normalised).
fn rail_direction(points: &[Vector3<f64>], c: &[f64]) -> Option<Vector3<f64>> {
    let mut a = DMatrix::zeros(points.len(), 8);
    let mut y = DVector::zeros(points.len());
    for (k, (p, &q)) in points.iter().zip(c).enumerate() {
        for j in 0..3 {
            a[(k, j)] = 2.0 * p[j];
            a[(k, 3 + j)] = 2.0 * q * p[j];
        }
        a[(k, 6)] = -2.0 * q;
        a[(k, 7)] = -1.0;
        y[k] = p.norm_squared() + q * q;
    }
    let s = a.svd(true, true).solve(&y, 1e-14).ok()?;
    Vector3::new(s[3], s[4], s[5]).try_normalize(1e-12)
}

/// Klipper's parameters of a linear delta model: see the module docs and [`KlipperOptions`].
pub fn from_model(file: &ModelFile, opts: &KlipperOptions) -> Result<KlipperFit, ControllerError> {
    let m = file.mechanism.build();
    let inputs = file.mechanism.inputs();
    if !matches!(file.mechanism, MechanismSpec::Limbs(_)) || inputs.len() != 3 || m.task() != crate::model::Task::Position {
        return Err(ControllerError::Unsupported(format!(
            "Klipper's delta kinematics describe three carriages moving a translating nozzle; this is a {} mechanism with {} inputs",
            file.mechanism.kind(),
            inputs.len()
        )));
    }
    let upper = endstop_inputs(&inputs)?;
    // The nozzle: the platform origin in the base frame, or with a bed the tool point in the
    // frame the bed was found in; seen from the bed's frame.
    let full = file.build();
    let model: &dyn Mechanism = if opts.bed.is_some() { &*full } else { &*m };
    let bed_frame = opts.bed.map_or(Pose::identity(), |b| b.frame());
    let configurations = spread_configurations(model, &inputs, 300, super::PROJECTION_SEED + 2)?;
    let points = configurations
        .iter()
        .map(|q| {
            Ok(bed_frame
                .inverse_transform_point(&model.forward(q)?.translation.vector.into())
                .coords)
        })
        .collect::<Result<Vec<_>, KinError>>()?;
    // Per tower: (c + o − z)² + (tx − x)² + (ty − y)² = L², linear in (o, tx, ty, K = o² + tx² + ty² − L²):
    // (c − z)² + x² + y² = −2o(c − z) + 2 tx x + 2 ty y − K.
    let mut towers = [[0.0; 4]; 3];
    for (i, tower) in towers.iter_mut().enumerate() {
        let mut a = DMatrix::zeros(points.len(), 4);
        let mut y = DVector::zeros(points.len());
        for (k, (p, q)) in points.iter().zip(&configurations).enumerate() {
            let cz = q[i] - p.z;
            a[(k, 0)] = -2.0 * cz;
            a[(k, 1)] = 2.0 * p.x;
            a[(k, 2)] = 2.0 * p.y;
            a[(k, 3)] = -1.0;
            y[k] = cz * cz + p.x * p.x + p.y * p.y;
        }
        let s = a
            .svd(true, true)
            .solve(&y, 1e-14)
            .map_err(|e| ControllerError::Unsupported(format!("tower fit: {e}")))?;
        let l2 = s[0] * s[0] + s[1] * s[1] + s[2] * s[2] - s[3];
        *tower = [s[0], s[1], s[2], l2.max(0.0).sqrt()];
    }
    // The circle through the three towers.
    let (a, b, c) = (
        Vector3::new(towers[0][1], towers[0][2], 0.0),
        Vector3::new(towers[1][1], towers[1][2], 0.0),
        Vector3::new(towers[2][1], towers[2][2], 0.0),
    );
    let (ab, ac) = (b - a, c - a);
    let cross = ab.cross(&ac);
    let centre = a + (ac.norm_squared() * cross.cross(&ab) + ab.norm_squared() * ac.cross(&cross)) / (2.0 * cross.norm_squared());
    let radius = (a - centre).norm();
    let mut x = DVector::zeros(12);
    x[0] = radius;
    for i in 0..3 {
        let t = Vector3::new(towers[i][1], towers[i][2], 0.0) - centre;
        x[1 + i] = t.y.atan2(t.x);
        x[4 + i] = towers[i][3];
        x[7 + i] = towers[i][0];
    }
    x[10] = centre.x;
    x[11] = centre.y;
    let residual = |x: &DVector<f64>| -> Result<DVector<f64>, KinError> {
        let (k, off, o) = unpack(x, &upper);
        let mut r = DVector::zeros(3 * points.len());
        for (n, (p, q)) in points.iter().zip(&configurations).enumerate() {
            let h = [q[0] + off[0], q[1] + off[1], q[2] + off[2]];
            let e = k.forward(&h)? + Vector3::new(o[0], o[1], 0.0) - p;
            r.fixed_rows_mut::<3>(3 * n).copy_from(&e);
        }
        Ok(r)
    };
    let start = residual(&x)?;
    let start_max = start.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (x, r) = if start_max > 1e-9 {
        least_squares(x, 1e-6, 30, residual)?
    } else {
        (x, start)
    };
    let worst = r.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let mut lost = Vec::new();
    if worst > 1e-9 {
        lost.push(format!(
            "geometry beyond Klipper's towers, arm lengths and endstops (rail tilts, parallelogram and joint-axis errors): nozzle positions off by up to {} mm over the fit",
            fixed(worst, 9)
        ));
    }
    // Which of the model's free parameters: their effect on the nozzle outside the span of
    // Klipper's parameters, over 100 of the configurations.
    let subset = &configurations[..configurations.len().min(100)];
    let sub_points = &points[..subset.len()];
    let sub_residual = |x: &DVector<f64>| -> Result<DVector<f64>, KinError> {
        let (k, off, o) = unpack(x, &upper);
        let mut r = DVector::zeros(3 * sub_points.len());
        for (n, (p, q)) in sub_points.iter().zip(subset).enumerate() {
            let h = [q[0] + off[0], q[1] + off[1], q[2] + off[2]];
            let e = k.forward(&h)? + Vector3::new(o[0], o[1], 0.0) - p;
            r.fixed_rows_mut::<3>(3 * n).copy_from(&e);
        }
        Ok(r)
    };
    let mut jk = DMatrix::zeros(3 * subset.len(), x.len());
    for c in 0..x.len() {
        let (mut xp, mut xm) = (x.clone(), x.clone());
        xp[c] += 1e-6;
        xm[c] -= 1e-6;
        jk.set_column(c, &((sub_residual(&xp)? - sub_residual(&xm)?) / 2e-6));
    }
    // Klipper's columns in the model's frame (the bed's frame turned back).
    let turn_back = bed_frame.rotation.to_rotation_matrix();
    for n in 0..subset.len() {
        for c in 0..x.len() {
            let v = turn_back * Vector3::new(jk[(3 * n, c)], jk[(3 * n + 1, c)], jk[(3 * n + 2, c)]);
            for a in 0..3 {
                jk[(3 * n + a, c)] = v[a];
            }
        }
    }
    // The free parameters of the machine itself (not its frames), indexed in `model`.
    let free = file.free_indices().map_err(|e| ControllerError::Unsupported(e.to_string()))?;
    let all = full.params();
    let own = m.params();
    let params = model.params();
    let free: Vec<usize> = free
        .iter()
        .filter(|&&i| own.iter().any(|p| p.name == all[i].name))
        .filter_map(|&i| params.iter().position(|p| p.name == all[i].name))
        .collect();
    for (j, fraction, outside) in unrepresented_positions(model, &free, subset, &jk, 1e-6, 1e-3)? {
        let (per, unit) = match params[j].unit {
            crate::params::Unit::Angle => (outside * 1f64.to_radians(), "°"),
            _ => (outside, "mm"),
        };
        // Below what the file's figures show: no motion worth naming.
        if per < 5e-7 {
            continue;
        }
        lost.push(format!(
            "{}: {} mm RMS of nozzle motion per {unit} of error ({} % of its effect) outside Klipper's parameters",
            params[j].name,
            fixed(per, 6),
            fixed(100.0 * fraction, 1)
        ));
    }
    let (mut k, _, o) = unpack(&x, &upper);
    // Tower c where asked: the frame turned about z.
    let turn = match opts.angle_c {
        Some(a) => (k.angle[2] - a).to_radians(),
        None => 0.0,
    };
    for a in k.angle.iter_mut() {
        *a -= turn.to_degrees();
    }
    let frame = bed_frame
        * Pose::from_parts(
            nalgebra::Translation3::new(o[0], o[1], 0.0),
            nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), turn),
        );
    // Each rail's lean from Klipper's z (the bed's normal), in Klipper's frame.
    for (i, t) in TOWERS.iter().enumerate() {
        let c: Vec<f64> = configurations.iter().map(|q| q[i]).collect();
        let Some(d) = rail_direction(&points, &c) else { continue };
        let d = nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), -turn) * if d.z < 0.0 { -d } else { d };
        let lean = d.z.clamp(-1.0, 1.0).acos().to_degrees();
        if lean > 1e-6 {
            lost.push(format!(
                "tower {t}'s rail leans {}° from Klipper's z ({}): toward x {}°, toward y {}° (Klipper's towers are parallel to z)",
                fixed(lean, 6),
                if opts.bed.is_some() { "the bed's normal" } else { "the model's z" },
                fixed(d.x.atan2(d.z).to_degrees(), 6),
                fixed(d.y.atan2(d.z).to_degrees(), 6)
            ));
        }
    }
    Ok(KlipperFit {
        delta: k,
        frame,
        fit_residual_mm: worst,
        lost,
    })
}

/// The Klipper delta sections of a linear delta model (see the module docs) and what they
/// leave, Klipper's frame where the model's base frame puts it.
pub fn export(file: &ModelFile) -> Result<Export, ControllerError> {
    export_with(file, &KlipperOptions::default())
}

/// [`export`] with Klipper's frame on a bed and tower c's angle ([`KlipperOptions`]).
pub fn export_with(file: &ModelFile, opts: &KlipperOptions) -> Result<Export, ControllerError> {
    let fit = from_model(file, opts)?;
    let text = fit.delta.to_text();
    let read = KlipperDelta::parse(&text)?;
    let full = file.build();
    let m = file.mechanism.build();
    let model: &dyn Mechanism = if opts.bed.is_some() { &*full } else { &*m };
    let inputs = file.mechanism.inputs();
    let upper = endstop_inputs(&inputs)?;
    let configurations = spread_configurations(model, &inputs, super::PROJECTION_POSES, super::PROJECTION_SEED)?;
    let pairs = configurations
        .iter()
        .map(|q| {
            let t = model.forward(q)?;
            // The carriage at input q: Klipper's height is q shifted so that the endstop input
            // (the upper limit) is Klipper's endstop height.
            let h: [f64; 3] = std::array::from_fn(|i| q[i] - upper[i] + read.endstop_height(i));
            let p = fit.frame.transform_point(&read.forward(&h)?.into()).coords;
            Ok((t, Pose::translation(p.x, p.y, p.z)))
        })
        .collect::<Result<Vec<_>, KinError>>()?;
    let o = fit.frame.translation.vector;
    let mut not_written = Vec::new();
    match opts.bed {
        None => {
            not_written.push(format!(
                "Klipper's origin (the towers' circle centre) at ({}, {}) mm in the model's base frame: Klipper's x, y are the model's minus it",
                fixed(o.x, 6),
                fixed(o.y, 6)
            ));
            if file.frames.is_some() {
                not_written.push("measurement and tool frames of the calibration: the nozzle is the platform frame's origin".into());
            }
        }
        Some(bed) => {
            let x = fit.frame.rotation * Vector3::x();
            not_written.push(format!(
                "Klipper's frame on the bed: origin (below the towers' circle centre) at ({}, {}, {}) mm, z along ({}, {}, {}), x along ({}, {}, {}) in the model's frame; the nozzle is the model's tool point",
                fixed(o.x, 6),
                fixed(o.y, 6),
                fixed(o.z, 6),
                fixed(bed.normal.x, 9),
                fixed(bed.normal.y, 9),
                fixed(bed.normal.z, 9),
                fixed(x.x, 9),
                fixed(x.y, 9),
                fixed(x.z, 9)
            ));
        }
    }
    Ok(Export {
        text,
        projection: Projection {
            difference: PoseDifference::of(&pairs, false),
            not_represented: fit.lost,
            fit_residual_mm: Some(fit.fit_residual_mm),
            not_written,
        },
    })
}

/// A linear delta model file of Klipper's delta sections (see the module docs).
pub fn import(text: &str) -> Result<ModelFile, ControllerError> {
    KlipperDelta::parse(text)?.model_file()
}
