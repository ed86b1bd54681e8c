//! Reading model files: the checks and conversions of [`Ctx`] (spans, units, array lengths,
//! poses, joints, DH tables).
use super::*;

/// Fixed lengths of the numeric arrays of model files, by key: serde reads the first `n` values
/// of a longer TOML array and drops the rest, so a typo such as `c = [0, 100, 0, 5]` would pass
/// silently without this check.
const ARRAY_LENGTHS: [(&str, usize); 25] = [
    ("gravity_direction", 3),
    ("position", 3),
    ("rpy", 3),
    ("rotvec", 3),
    ("axis", 3),
    ("b", 3),
    ("c", 3),
    ("base", 3),
    ("platform", 3),
    ("euler_xyz", 3),
    ("alpha", 2),
    ("beta", 2),
    ("gamma", 2),
    ("limits", 2),
    ("stroke", 2),
    ("sub_stroke", 2),
    ("x", 2),
    ("y", 2),
    ("z", 2),
    ("sub_loop", 4),
    ("platform_point", 3),
    ("position_min", 3),
    ("position_max", 3),
    ("rpy_min", 3),
    ("rpy_max", 3),
];

impl Ctx<'_> {
    /// Every array under a key of [`ARRAY_LENGTHS`] has exactly that many values.
    pub(super) fn check_array_lengths(&self) -> Result<(), IoError> {
        use toml::de::{DeTable, DeValue};
        fn walk(ctx: &Ctx<'_>, table: &DeTable<'_>, prefix: &str) -> Result<(), IoError> {
            for (k, v) in table.iter() {
                let key = k.get_ref().as_ref();
                let full = if prefix.is_empty() {
                    key.to_string()
                } else {
                    format!("{prefix}.{key}")
                };
                match v.get_ref() {
                    DeValue::Table(t) => walk(ctx, t, &full)?,
                    DeValue::Array(items) => {
                        if let Some(&(_, n)) = ARRAY_LENGTHS.iter().find(|(name, _)| *name == key) {
                            if items.len() != n {
                                return Err(ctx.at(&v.span(), format!("{full}: expected {n} values, found {}", items.len())));
                            }
                        }
                        for item in items {
                            if let DeValue::Table(t) = item.get_ref() {
                                walk(ctx, t, &full)?;
                            }
                        }
                    }
                    _ => {}
                }
            }
            Ok(())
        }
        let table = DeTable::parse(self.text).map_err(|e| self.toml_error(&e))?;
        walk(self, table.get_ref(), "")
    }

    pub(super) fn line_of(&self, offset: usize) -> usize {
        self.text[..offset.min(self.text.len())].matches('\n').count() + 1
    }

    pub(super) fn at(&self, span: &Range<usize>, message: String) -> IoError {
        IoError::AtLine {
            path: self.path.to_path_buf(),
            line: self.line_of(span.start),
            message,
        }
    }

    pub(super) fn toml_error(&self, e: &toml::de::Error) -> IoError {
        let message = e.message().trim().replace('\n', "; ");
        match e.span() {
            // The line itself, so that the reader sees what the parser could not read.
            Some(s) => {
                let start = self.text[..s.start.min(self.text.len())].rfind('\n').map_or(0, |i| i + 1);
                let end = self.text[start..].find('\n').map_or(self.text.len(), |i| start + i);
                let line = self.text[start..end].trim();
                match line.is_empty() || line.chars().count() > 120 {
                    true => self.at(&s, message),
                    false => self.at(&s, format!("`{line}`: {message}")),
                }
            }
            None => IoError::Invalid {
                path: self.path.to_path_buf(),
                message,
            },
        }
    }

    pub(super) fn units(&self, raw: &RawUnits) -> Result<Units, IoError> {
        let length = LengthUnit::parse(raw.length.get_ref()).ok_or_else(|| {
            self.at(
                &raw.length.span(),
                format!("units.length: unknown length unit '{}' (use \"mm\" or \"m\")", raw.length.get_ref()),
            )
        })?;
        let angle = AngleUnit::parse(raw.angle.get_ref()).ok_or_else(|| {
            self.at(
                &raw.angle.span(),
                format!("units.angle: unknown angle unit '{}' (use \"deg\" or \"rad\")", raw.angle.get_ref()),
            )
        })?;
        Ok(Units { length, angle })
    }

    pub(super) fn pose(
        &self,
        span: &Range<usize>,
        what: &str,
        position: Option<[f64; 3]>,
        rpy: Option<[f64; 3]>,
        rotvec: Option<[f64; 3]>,
        units: &Units,
    ) -> Result<Pose, IoError> {
        let all = position.iter().chain(rpy.iter()).chain(rotvec.iter()).flatten();
        if all.clone().any(|v| !v.is_finite()) {
            return Err(self.at(span, format!("{what}: non-finite value in position/rpy/rotvec")));
        }
        let p = Vector3::from(position.unwrap_or([0.0; 3])) * units.length.to_mm();
        let f = units.angle.to_rad();
        let rot = match (rpy, rotvec) {
            (Some(_), Some(_)) => return Err(self.at(span, format!("{what}: give either 'rpy' or 'rotvec', not both"))),
            (Some(r), None) => UnitQuaternion::from_euler_angles(r[0] * f, r[1] * f, r[2] * f),
            (None, Some(v)) => crate::se3::so3_exp(&(Vector3::from(v) * f)),
            (None, None) => UnitQuaternion::identity(),
        };
        Ok(Pose::from_parts(Translation3::from(p), rot))
    }

    pub(super) fn limits(
        &self,
        span: &Range<usize>,
        what: &str,
        limits: Option<[f64; 2]>,
        kind: JointKind,
        units: &Units,
    ) -> Result<Option<(f64, f64)>, IoError> {
        let Some([lo, hi]) = limits else { return Ok(None) };
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(self.at(
                span,
                format!("{what}.limits: need two finite values with min < max, got [{lo}, {hi}]"),
            ));
        }
        let f = match kind {
            JointKind::Revolute => units.angle.to_rad(),
            JointKind::Prismatic => units.length.to_mm(),
        };
        Ok(Some((lo * f, hi * f)))
    }

    pub(super) fn serial(&self, name: &str, raw: &RawSerial, units: &Units) -> Result<MechanismSpec, IoError> {
        let spec = self.serial_chain(name, raw, units)?;
        let (Some(raw_terms), MechanismSpec::Serial(chain)) = (&raw.joint_terms, &spec) else {
            return Ok(spec);
        };
        self.joint_terms(chain, raw_terms, units)
    }

    /// `[mechanism.joint_terms]` of a serial chain.
    fn joint_terms(&self, chain: &SerialChain, raw: &Spanned<RawJointTerms>, units: &Units) -> Result<MechanismSpec, IoError> {
        let span = raw.span();
        let r = raw.get_ref();
        let n = chain.n_joints();
        let index = |key: &str, name: &Spanned<String>, tool: bool| -> Result<usize, IoError> {
            if tool && name.get_ref() == "tool" {
                return Ok(n);
            }
            chain.joints().iter().position(|j| &j.name == name.get_ref()).ok_or_else(|| {
                let names: Vec<&str> = chain.joints().iter().map(|j| j.name.as_str()).collect();
                self.at(
                    &name.span(),
                    format!(
                        "mechanism.joint_terms.{key}: no joint '{}' in this chain (joints: {}{})",
                        name.get_ref(),
                        names.join(", "),
                        if tool { ", or \"tool\"" } else { "" }
                    ),
                )
            })
        };
        let list = |key: &str, v: &Option<Vec<Spanned<String>>>, tool: bool| -> Result<Vec<usize>, IoError> {
            v.iter().flatten().map(|x| index(key, x, tool)).collect()
        };
        let backlash = list("backlash", &r.backlash, false)?;
        let gravity = list("gravity", &r.gravity, false)?;
        let harmonic = list("harmonic", &r.harmonic, false)?;
        let loads = match &r.loads {
            Some(_) => list("loads", &r.loads, true)?,
            None => JointTerms::default_loads(chain, &gravity),
        };
        let gravity_direction = match r.gravity_direction {
            Some(g) => {
                let v = Vector3::from(g);
                if !v.iter().all(|x| x.is_finite()) || v.norm() < 1e-9 {
                    return Err(self.at(
                        &span,
                        "mechanism.joint_terms.gravity_direction: must be a finite non-zero vector".into(),
                    ));
                }
                v.normalize()
            }
            None => -Vector3::z(),
        };
        let mut terms = JointTerms {
            backlash,
            gravity,
            loads,
            gravity_direction,
            harmonic,
            values: Vec::new(),
        };
        terms.values = vec![0.0; terms.n_params()];
        let model = WithJointTerms::new(chain.clone(), terms.clone()).map_err(|e| self.at(&span, format!("mechanism.joint_terms: {e}")))?;
        if let Some(values) = &r.values {
            let params = model.params();
            let first = chain.n_params();
            for (key, v) in values.get_ref() {
                let Some(k) = params[first..].iter().position(|p| &p.name == key) else {
                    let names: Vec<&str> = params[first..].iter().map(|p| p.name.as_str()).collect();
                    return Err(self.at(
                        &values.span(),
                        format!(
                            "mechanism.joint_terms.values: '{key}' is not a term of this model (terms: {})",
                            names.join(", ")
                        ),
                    ));
                };
                if !v.is_finite() {
                    return Err(self.at(&values.span(), format!("mechanism.joint_terms.values.{key}: not a finite number")));
                }
                terms.values[k] = v * units.angle.to_rad();
            }
        }
        let mut model = WithJointTerms::new(chain.clone(), terms).map_err(|e| self.at(&span, format!("mechanism.joint_terms: {e}")))?;
        if let Some(rows) = &r.reference {
            let bad = |m: String| self.at(&rows.span(), format!("mechanism.joint_terms.reference: {m}"));
            if rows.get_ref().len() != n + 1 {
                return Err(bad(format!(
                    "{} rows for {} joints and the tool (one [x, y, z, roll, pitch, yaw] per joint, then the tool)",
                    rows.get_ref().len(),
                    n
                )));
            }
            let mut reference = chain.clone();
            for (k, row) in rows.get_ref().iter().enumerate() {
                if row.len() != 6 || row.iter().any(|v| !v.is_finite()) {
                    return Err(bad(format!("row {k}: need six finite numbers [x, y, z, roll, pitch, yaw]")));
                }
                let (l, a) = (units.length.to_mm(), units.angle.to_rad());
                let rot = UnitQuaternion::from_euler_angles(row[3] * a, row[4] * a, row[5] * a);
                reference.set_initial_pose(k, Pose::from_parts(Translation3::new(row[0] * l, row[1] * l, row[2] * l), rot));
            }
            model = model.with_reference(reference).map_err(bad)?;
        }
        Ok(MechanismSpec::SerialTerms(model))
    }

    fn serial_chain(&self, name: &str, raw: &RawSerial, units: &Units) -> Result<MechanismSpec, IoError> {
        let forms = [raw.joints.is_some(), raw.dh.is_some(), raw.mdh.is_some()];
        if forms.iter().filter(|f| **f).count() != 1 {
            return Err(IoError::Invalid {
                path: self.path.to_path_buf(),
                message: "mechanism: a serial chain needs exactly one of [[mechanism.joints]] (local POE), [[mechanism.dh]] (standard DH) or [[mechanism.mdh]] (modified DH)".into(),
            });
        }
        if let Some(rows) = raw.dh.as_ref().or(raw.mdh.as_ref()) {
            let convention = if raw.dh.is_some() {
                DhConvention::Standard
            } else {
                DhConvention::Modified
            };
            return self.dh_table(name, convention, rows, raw, units);
        }
        if let Some(b) = &raw.base {
            return Err(self.at(
                &b.span(),
                "mechanism.base: only with a DH table ([[mechanism.dh]] or [[mechanism.mdh]]); with [[mechanism.joints]] the first joint's position/rpy is the base".into(),
            ));
        }
        let raw_joints = raw.joints.as_deref().unwrap_or_default();
        if raw_joints.is_empty() {
            return Err(IoError::Invalid {
                path: self.path.to_path_buf(),
                message: "mechanism.joints: a serial chain needs at least one joint".into(),
            });
        }
        let mut joints = Vec::new();
        let mut initial = Vec::new();
        for (j, sj) in raw_joints.iter().enumerate() {
            let span = sj.span();
            let rj = sj.get_ref();
            let what = format!("mechanism.joints[{j}] ('{}')", rj.name);
            if rj.name.is_empty() || joints.iter().any(|x: &ChainJoint| x.name == rj.name) {
                return Err(self.at(&span, format!("{what}: joint names must be non-empty and unique")));
            }
            let axis = Vector3::from(rj.axis);
            if !axis.iter().all(|v| v.is_finite()) || axis.norm() < 1e-9 {
                return Err(self.at(&span, format!("{what}.axis: must be a finite non-zero vector")));
            }
            let mut joint = match rj.kind {
                JointKind::Revolute => ChainJoint::revolute(rj.name.clone(), axis),
                JointKind::Prismatic => ChainJoint::prismatic(rj.name.clone(), axis),
            };
            joint.limits = self.limits(&span, &what, rj.limits, rj.kind, units)?;
            joints.push(joint);
            initial.push(self.pose(&span, &what, rj.position, rj.rpy, rj.rotvec, units)?);
        }
        let tool = match &raw.tool {
            Some(t) => {
                let r = t.get_ref();
                self.pose(&t.span(), "mechanism.tool", r.position, r.rpy, r.rotvec, units)?
            }
            None => Pose::identity(),
        };
        Ok(MechanismSpec::Serial(SerialChain::new(name, joints, initial, tool)))
    }

    pub(super) fn dh_table(
        &self,
        name: &str,
        convention: DhConvention,
        rows: &[Spanned<RawDhRow>],
        raw: &RawSerial,
        units: &Units,
    ) -> Result<MechanismSpec, IoError> {
        let key = convention.key();
        if rows.is_empty() {
            return Err(IoError::Invalid {
                path: self.path.to_path_buf(),
                message: format!("mechanism.{key}: a DH table needs at least one row"),
            });
        }
        let (l, a) = (units.length.to_mm(), units.angle.to_rad());
        let mut joints: Vec<DhJoint> = Vec::new();
        for (j, sr) in rows.iter().enumerate() {
            let span = sr.span();
            let r = sr.get_ref();
            let what = format!("mechanism.{key}[{j}] ('{}')", r.name);
            if r.name.is_empty() || joints.iter().any(|x| x.name == r.name) {
                return Err(self.at(&span, format!("{what}: joint names must be non-empty and unique")));
            }
            let values = [r.a, r.alpha, r.d, r.theta, r.beta.unwrap_or(0.0)];
            if values.iter().any(|v| !v.is_finite()) {
                return Err(self.at(&span, format!("{what}: non-finite value in a, alpha, d, theta or beta")));
            }
            if r.beta.is_some() && convention == DhConvention::Modified {
                return Err(self.at(
                    &span,
                    format!("{what}.beta: Hayati's beta belongs to standard DH ([[mechanism.dh]]), not to modified DH"),
                ));
            }
            joints.push(DhJoint {
                name: r.name.clone(),
                kind: r.kind,
                a: r.a * l,
                alpha: r.alpha * a,
                d: r.d * l,
                theta: r.theta * a,
                beta: r.beta.unwrap_or(0.0) * a,
                limits: self.limits(&span, &what, r.limits, r.kind, units)?,
            });
        }
        let pose = |p: &Option<Spanned<RawPose>>, what: &str| match p {
            Some(t) => {
                let r = t.get_ref();
                self.pose(&t.span(), what, r.position, r.rpy, r.rotvec, units)
            }
            None => Ok(Pose::identity()),
        };
        let table = DhTable {
            convention,
            base: pose(&raw.base, "mechanism.base")?,
            joints,
            tool: pose(&raw.tool, "mechanism.tool")?,
        };
        Ok(MechanismSpec::Serial(table.to_chain(name)))
    }

    pub(super) fn finish<M>(&self, raw: RawFile<M>, units: Units, mechanism: MechanismSpec) -> Result<ModelFile, IoError> {
        if let Some(i) = mechanism
            .data_columns()
            .into_iter()
            .find(|i| crate::io::data_file::is_measurement_column(&i.name))
        {
            return Err(IoError::Invalid {
                path: self.path.to_path_buf(),
                message: format!(
                    "joint '{0}': '{0}' names a measurement's columns in data files ({0}_mm, {0}_deg, …), which a joint's column would take: rename the joint (e.g. '{0}_axis')",
                    i.name
                ),
            });
        }
        let params = mechanism.build().params();
        let (free, fixed) = match &raw.calibration {
            Some(c) => (
                c.free.clone().unwrap_or_else(|| vec![Spanned::new(0..0, "*".to_string())]),
                c.fixed.clone().unwrap_or_default(),
            ),
            None => (vec![Spanned::new(0..0, "*".to_string())], Vec::new()),
        };
        for (key, list) in [("free", &free), ("fixed", &fixed)] {
            for pat in list {
                if !params.iter().any(|p| param_match(pat.get_ref(), &p.name)) {
                    let examples: Vec<&str> = params.iter().take(3).map(|p| p.name.as_str()).collect();
                    return Err(self.at(
                        &pat.span(),
                        format!(
                            "calibration.{key}: '{}' matches no parameter (names look like {}, …)",
                            pat.get_ref(),
                            examples.join(", ")
                        ),
                    ));
                }
            }
        }
        let mut tolerances = Tolerances::default();
        if let Some(c) = &raw.calibration {
            for (key, given, slot) in [
                ("tolerance_mm", &c.tolerance_mm, &mut tolerances.length_mm),
                ("tolerance_deg", &c.tolerance_deg, &mut tolerances.angle_deg),
            ] {
                if let Some(v) = given {
                    if !(v.get_ref().is_finite() && *v.get_ref() > 0.0) {
                        return Err(self.at(&v.span(), format!("calibration.{key}: must be finite and > 0")));
                    }
                    *slot = *v.get_ref();
                }
            }
        }
        let frames = match &raw.frames {
            Some(f) => {
                let pose = |p: &Spanned<RawPose>, what: &str| {
                    let r = p.get_ref();
                    self.pose(&p.span(), what, r.position, r.rpy, r.rotvec, &units)
                };
                Some(Frames {
                    measurement: pose(&f.measurement, "frames.measurement")?,
                    tool: pose(&f.tool, "frames.tool")?,
                })
            }
            None => None,
        };
        let covariance = match &raw.covariance {
            Some(c) => {
                let params = match &frames {
                    Some(f) => Framed::new(mechanism.build(), f.measurement, f.tool).params(),
                    None => params,
                };
                Some(self.covariance(c, &params)?)
            }
            None => None,
        };
        let noise = match &raw.noise {
            Some(n) => {
                let r = n.get_ref();
                let d = Noise::default();
                let (ea, el) = (
                    r.encoder_angle.map_or(d.joint_angle, |v| v * units.angle.to_rad()),
                    r.encoder_length.map_or(d.joint_length, |v| v * units.length.to_mm()),
                );
                if ![r.position, r.orientation, ea, el].iter().all(|v| *v > 0.0 && v.is_finite()) {
                    return Err(self.at(
                        &n.span(),
                        "noise: position, orientation, encoder_angle and encoder_length must be finite and > 0".into(),
                    ));
                }
                let mut kinds = crate::measure::KindNoise::default();
                for (kind, v) in [
                    (crate::measure::RowKind::Seat, r.seat),
                    (crate::measure::RowKind::Distance, r.distance),
                    (crate::measure::RowKind::Probe, r.probe),
                ] {
                    let Some(v) = v else { continue };
                    if !(v.is_finite() && v > 0.0) {
                        return Err(self.at(&n.span(), format!("noise: {} must be finite and > 0", kind.noise_key())));
                    }
                    *kinds.get_mut(kind).expect("an instrument kind") = Some(v * units.length.to_mm());
                }
                Some(Noise {
                    kinds,
                    position: r.position * units.length.to_mm(),
                    orientation: r.orientation * units.angle.to_rad(),
                    joint_angle: ea,
                    joint_length: el,
                })
            }
            None => None,
        };
        Ok(ModelFile {
            name: raw.name,
            description: raw.description,
            units,
            mechanism,
            free: free.into_iter().map(|s| s.into_inner()).collect(),
            fixed: fixed.into_iter().map(|s| s.into_inner()).collect(),
            tolerances,
            noise,
            provenance: raw.provenance,
            covariance,
            frames,
        })
    }
}

/// `[mechanism.joint_terms]` as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawJointTerms {
    pub(super) backlash: Option<Vec<Spanned<String>>>,
    pub(super) gravity: Option<Vec<Spanned<String>>>,
    pub(super) loads: Option<Vec<Spanned<String>>>,
    pub(super) gravity_direction: Option<[f64; 3]>,
    pub(super) harmonic: Option<Vec<Spanned<String>>>,
    pub(super) values: Option<Spanned<std::collections::BTreeMap<String, f64>>>,
    pub(super) reference: Option<Spanned<Vec<Vec<f64>>>>,
}
