//! Writing model files: the `[mechanism]` part of each kind, poses, DH tables, numbers.
use super::*;
use crate::model::Mechanism as _;

/// Write the `[noise]` section in `units` (the encoders' only when not the default).
pub(super) fn write_noise(n: &Noise, units: &Units, out: &mut String) {
    let (a, l) = (units.angle, units.length);
    let _ = write!(
        out,
        "\n[noise]  # measurement standard deviations, per axis\nposition = {}  # {}\norientation = {}  # {}\n",
        num(n.position / l.to_mm()),
        l.symbol(),
        num_per(n.orientation, a.to_rad()),
        a.symbol()
    );
    for kind in crate::measure::RowKind::ALL {
        if let Some(v) = n.kinds.get(kind) {
            let _ = writeln!(
                out,
                "{} = {}  # {}, {} rows",
                kind.noise_key(),
                num(v / l.to_mm()),
                l.symbol(),
                kind.name()
            );
        }
    }
    let d = Noise::default();
    if (n.joint_angle, n.joint_length) != (d.joint_angle, d.joint_length) {
        let (ea, el) = (num_per(n.joint_angle, a.to_rad()), num(n.joint_length / l.to_mm()));
        let _ = writeln!(
            out,
            "encoder_angle = {ea}  # {}, observed joints\nencoder_length = {el}  # {}",
            a.symbol(),
            l.symbol()
        );
    }
}

/// Write the `[mechanism]` part of a model file for `spec` in `units`.
pub(super) fn write_mechanism(spec: &MechanismSpec, units: &Units, out: &mut String) -> Result<(), String> {
    let (l, a) = (units.length.to_mm(), units.angle.to_rad());
    match spec {
        MechanismSpec::SerialTerms(m) => {
            write_mechanism(&MechanismSpec::Serial(m.chain().clone()), units, out)?;
            write_joint_terms(m, units, out);
        }
        MechanismSpec::Serial(c) => {
            out.push_str("[mechanism]\nkind = \"serial\"\n");
            out.push_str("# Joint j: position/rpy = T_{j-1,j}(0), the joint frame in the previous joint frame at zero\n");
            out.push_str("# joint values; axis = joint axis in that frame through its origin.\n");
            for (j, joint) in c.joints().iter().enumerate() {
                let t = joint.twist;
                let (kind, axis, rest) = match joint.kind {
                    JointKind::Revolute => ("revolute", [t[3], t[4], t[5]], [t[0], t[1], t[2]]),
                    JointKind::Prismatic => ("prismatic", [t[0], t[1], t[2]], [t[3], t[4], t[5]]),
                };
                if rest.iter().any(|v| v.abs() > 1e-12) {
                    return Err(format!(
                        "joint '{}': a joint twist with an offset cannot be written; put the offset in the joint's position",
                        joint.name
                    ));
                }
                let _ = write!(
                    out,
                    "\n[[mechanism.joints]]\nname = \"{}\"\ntype = \"{kind}\"\naxis = {}\n",
                    joint.name,
                    fmt3(axis)
                );
                if let Some((lo, hi)) = joint.limits {
                    let f = if joint.kind == JointKind::Revolute { a } else { l };
                    let _ = writeln!(out, "limits = [{}, {}]", num_per(lo, f), num_per(hi, f));
                }
                write_pose(&c.initial_poses()[j], units, out);
            }
            out.push_str("\n[mechanism.tool]\n");
            write_pose(c.tool(), units, out);
        }
        MechanismSpec::Pm5(m) => parallel::write_pm5(m, units, out),
        MechanismSpec::Stewart(m) => parallel::write_stewart(m, units, out),
        MechanismSpec::Limbs(m) => limbs::write_limbs(m, units, out)?,
    }
    Ok(())
}

/// `[mechanism.joint_terms]`: the terms, the load points written out, and every value by name.
fn write_joint_terms(m: &WithJointTerms, units: &Units, out: &mut String) {
    let t = m.terms();
    let names = |v: &[usize]| v.iter().map(|&j| quote(&m.load_name(j))).collect::<Vec<_>>().join(", ");
    out.push_str("\n[mechanism.joint_terms]\n");
    out.push_str(
        "# Non-geometric joint terms (docs/joint-terms.md): q_eff = q + backlash·dir_<joint> + Σ gravity·lever + cos·cos q + sin·sin q.\n",
    );
    let _ = writeln!(
        out,
        "backlash = [{}]  # lost motion; data columns dir_<joint> = -1, 0, +1",
        names(&t.backlash)
    );
    let _ = writeln!(out, "gravity = [{}]  # revolute joints that yield under gravity", names(&t.gravity));
    let _ = writeln!(
        out,
        "loads = [{}]  # load points: a joint's axis point, or \"tool\"",
        names(&t.loads)
    );
    let g = t.gravity_direction;
    let _ = writeln!(out, "gravity_direction = {}  # in the base frame", fmt3([g.x, g.y, g.z]));
    let _ = writeln!(out, "harmonic = [{}]  # first harmonic of the joint angle", names(&t.harmonic));
    if m.reference().geometry() != m.chain().geometry() {
        out.push_str("# The geometry the gravity levers are computed on (frozen when the terms were first identified):\n");
        out.push_str("# one [x, y, z, roll, pitch, yaw] per joint (its position/rpy), then the tool.\n");
        out.push_str("reference = [\n");
        for p in m.reference().initial_poses() {
            let t = p.translation.vector / units.length.to_mm();
            let r = crate::se3::rpy(&p.rotation);
            let a = units.angle.to_rad();
            let _ = writeln!(
                out,
                "    [{}, {}, {}, {}, {}, {}],",
                num(t.x),
                num(t.y),
                num(t.z),
                num(r[0] / a),
                num(r[1] / a),
                num(r[2] / a)
            );
        }
        out.push_str("]\n");
    }
    let _ = writeln!(
        out,
        "[mechanism.joint_terms.values]  # {}; gravity terms per metre of lever",
        units.angle.symbol()
    );
    let first = m.chain().n_params();
    for (p, v) in m.params()[first..].iter().zip(&t.values) {
        let _ = writeln!(out, "{} = {}", quote(&p.name), num_per(*v, units.angle.to_rad()));
    }
}

pub(super) fn quote(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

/// `v` as written in a file: a decimal of at most 12 significant digits when one lies within
/// 2e-15 (relative) of `v` — unit conversions do not leave `119.99999999999999` where the user
/// wrote `120` — else the shortest decimal that reads back as exactly `v` (calibrated values lose
/// nothing). Writing a value read from such a text gives the same text again. `-0.0` is `0.0`.
pub(super) fn num(v: f64) -> String {
    if v == 0.0 {
        return "0.0".into();
    }
    for prec in 0..12 {
        let s = format!("{v:.prec$e}");
        if let Ok(p) = s.parse::<f64>() {
            if (p - v).abs() <= 2e-15 * v.abs() {
                return format!("{p:?}");
            }
        }
    }
    format!("{v:?}")
}

/// The texts of `v` ([`num`]) that read back and written again stay the same: `reread` is what
/// reading the numbers and writing them again computes (a unit conversion, a rotation rebuilt
/// from its angles), which moves them by a few units in the last place. Each value is first put
/// on `grid` (coarser than that movement), so the re-read value falls back on the same grid
/// point; should one not (it lay on a boundary of the grid), the re-read's text is taken, which
/// does.
pub(super) fn stable<const N: usize>(v: [f64; N], grid: fn(f64) -> f64, reread: impl Fn([f64; N]) -> [f64; N]) -> [String; N] {
    let mut text = v.map(|x| num(grid(x)));
    for _ in 0..4 {
        let read = text.clone().map(|t| t.parse::<f64>().unwrap_or(f64::NAN));
        let again = reread(read).map(|x| num(grid(x)));
        if again == text {
            break;
        }
        text = again;
    }
    text
}

/// `x` to 15 significant digits (a unit conversion moves a value by about 1e-16 of itself).
fn significant15(x: f64) -> f64 {
    format!("{x:.14e}").parse().unwrap_or(x)
}

/// `x` to 12 decimal places (a rotation rebuilt from its angles moves them by about 1e-15 of a
/// degree or radian, whatever their size).
fn decimals12(x: f64) -> f64 {
    let r = (x * 1e12).round() / 1e12;
    if r.is_finite() {
        r
    } else {
        x
    }
}

/// `v / f` as [`num`] writes it (to 15 significant digits), the same text when read back
/// (times `f`) and written again.
pub(super) fn num_per(v: f64, f: f64) -> String {
    let [t] = stable([v / f], significant15, |[x]| [x * f / f]);
    t
}

pub(super) fn fmt3(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", num(v[0]), num(v[1]), num(v[2]))
}

/// Writes `position` and `rpy` ([`crate::se3::rpy`]), or `rotvec` where roll/pitch/yaw would
/// not give the rotation back to 1e-14 rad. The angles are written to 12 decimal places of their
/// unit ([`stable`]): read back and written again, a pose gives the same text.
pub(super) fn write_pose(p: &Pose, units: &Units, out: &mut String) {
    let t = p.translation.vector / units.length.to_mm();
    let f = units.angle.to_rad();
    let _ = writeln!(out, "position = {}", fmt3([t.x, t.y, t.z]));
    let [roll, pitch, yaw] = crate::se3::rpy(&p.rotation);
    let back = UnitQuaternion::from_euler_angles(roll, pitch, yaw);
    if crate::se3::so3_log(&(back.inverse() * p.rotation)).norm() <= 1e-14 {
        // As the reader rebuilds the rotation: the angles times `f`, then roll, pitch, yaw.
        let [r, p, y] = stable([roll / f, pitch / f, yaw / f], decimals12, |[r, p, y]| {
            crate::se3::rpy(&UnitQuaternion::from_euler_angles(r * f, p * f, y * f)).map(|a| a / f)
        });
        let _ = writeln!(out, "rpy = [{r}, {p}, {y}]");
    } else {
        let v = crate::se3::so3_log(&p.rotation) / f;
        let [x, y, z] = stable([v.x, v.y, v.z], decimals12, |v| {
            let back = crate::se3::so3_log(&crate::se3::so3_exp(&(nalgebra::Vector3::from(v) * f))) / f;
            [back.x, back.y, back.z]
        });
        let _ = writeln!(out, "rotvec = [{x}, {y}, {z}]");
    }
}

pub(super) fn write_dh(table: &DhTable, units: &Units, out: &mut String) {
    let (l, a) = (units.length.to_mm(), units.angle.to_rad());
    let key = table.convention.key();
    out.push_str("[mechanism]\nkind = \"serial\"\n");
    match table.convention {
        DhConvention::Standard => {
            out.push_str("# Standard DH: A_i(q) = Rz(theta + q)·Tz(d)·Tx(a)·Rx(alpha)·Ry(beta) (q adds to d for prismatic\n");
            out.push_str("# joints; beta is Hayati's, 0 when absent); g(q) = base · A_1(q_1) ··· A_n(q_n) · tool.\n");
        }
        DhConvention::Modified => {
            out.push_str("# Modified DH (Craig): A_i(q) = Rx(alpha)·Tx(a)·Rz(theta + q)·Tz(d), row i holding alpha_{i-1}\n");
            out.push_str("# and a_{i-1} (q adds to d for prismatic joints); g(q) = base · A_1(q_1) ··· A_n(q_n) · tool.\n");
        }
    }
    out.push_str("\n[mechanism.base]  # frame 0 in the world frame\n");
    write_pose(&table.base, units, out);
    for j in &table.joints {
        let kind = match j.kind {
            JointKind::Revolute => "revolute",
            JointKind::Prismatic => "prismatic",
        };
        let _ = write!(
            out,
            "\n[[mechanism.{key}]]\nname = {}\ntype = \"{kind}\"\na = {}\nalpha = {}\nd = {}\ntheta = {}\n",
            quote(&j.name),
            num(j.a / l),
            num(j.alpha / a),
            num(j.d / l),
            num(j.theta / a)
        );
        if j.beta != 0.0 {
            let _ = writeln!(
                out,
                "beta = {}  # Hayati: this joint's next axis is nearly parallel to it",
                num(j.beta / a)
            );
        }
        if let Some((lo, hi)) = j.limits {
            let f = if j.kind == JointKind::Revolute { a } else { l };
            let _ = writeln!(out, "limits = [{}, {}]", num_per(lo, f), num_per(hi, f));
        }
    }
    out.push_str("\n[mechanism.tool]  # the tool in the last DH frame\n");
    write_pose(&table.tool, units, out);
}
