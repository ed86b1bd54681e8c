//! A model with joint terms fitted again with fewer terms: the geometric model alone and each kind
//! of term alone, on the same data ([`crate::report::ModelVariant`]), so that a report shows what
//! each term contributes and whether it helps on held-out poses.
use super::{calibrate, CalibrationOptions};
use crate::io::data_file::DataSet;
use crate::io::model_file::{param_match, MechanismSpec, ModelFile};
use crate::model::joint_terms::{JointTerms, WithJointTerms};
use crate::report::ModelVariant;

/// The variants of `model` (a serial chain with joint terms; none for other models), each
/// calibrated like the full model but from one start and without variants of its own. A variant
/// that fails to calibrate is left out.
pub fn variants(model: &ModelFile, data: &DataSet, validation: Option<&DataSet>, opts: &CalibrationOptions) -> Vec<ModelVariant> {
    let MechanismSpec::SerialTerms(m) = &model.mechanism else {
        return Vec::new();
    };
    let t = m.terms();
    let kinds: Vec<(&str, JointTerms)> = [
        ("backlash", !t.backlash.is_empty(), only(t, true, false, false)),
        ("gravity", !t.gravity_pairs().is_empty(), only(t, false, true, false)),
        ("harmonic", !t.harmonic.is_empty(), only(t, false, false, true)),
    ]
    .into_iter()
    .filter(|(_, present, _)| *present)
    .map(|(name, _, terms)| (name, terms))
    .collect();
    let mut out: Vec<(String, ModelFile)> = vec![(
        "geometric only".into(),
        with_mechanism(model, MechanismSpec::Serial(m.chain().clone())),
    )];
    if kinds.len() > 1 {
        for (name, terms) in kinds {
            if let Ok(w) = WithJointTerms::new(m.chain().clone(), terms).and_then(|w| w.with_reference(m.reference().clone())) {
                out.push((format!("geometry + {name}"), with_mechanism(model, MechanismSpec::SerialTerms(w))));
            }
        }
    }
    let opts = CalibrationOptions {
        starts: 1,
        compare_terms: false,
        ..opts.clone()
    };
    out.into_iter()
        .filter_map(|(name, file)| {
            let c = calibrate(
                &file,
                &for_inputs(data, &file),
                validation.map(|v| for_inputs(v, &file)).as_ref(),
                &opts,
            )
            .ok()?;
            Some(ModelVariant {
                name,
                rank: c.report.rank,
                free: c.report.free,
                sigma0: c.report.sigma0,
                identification: c.report.identification.after_stats,
                validation: c.report.validation.as_ref().map(|v| v.after_stats),
            })
        })
        .collect()
}

/// `data` with the inputs of `file`, a variant's: a prefix of the full model's (the joint values,
/// then the approach directions when the variant keeps the lost motion).
fn for_inputs(data: &DataSet, file: &ModelFile) -> DataSet {
    let mut d = data.clone();
    let n = file.inputs().len();
    for m in d.measurements.iter_mut() {
        m.q.truncate(n);
    }
    d
}

/// `terms` keeping only the chosen kinds (values zero: a variant starts from no term).
fn only(t: &JointTerms, backlash: bool, gravity: bool, harmonic: bool) -> JointTerms {
    let mut out = JointTerms {
        backlash: if backlash { t.backlash.clone() } else { Vec::new() },
        gravity: if gravity { t.gravity.clone() } else { Vec::new() },
        loads: if gravity { t.loads.clone() } else { Vec::new() },
        gravity_direction: t.gravity_direction,
        harmonic: if harmonic { t.harmonic.clone() } else { Vec::new() },
        values: Vec::new(),
    };
    out.values = vec![0.0; out.n_params()];
    out
}

/// `model` with another mechanism; its free/fixed patterns keep those that still match a
/// parameter (they may name terms the variant does not have).
fn with_mechanism(model: &ModelFile, mechanism: MechanismSpec) -> ModelFile {
    let mut f = model.clone();
    let params = mechanism.build().params();
    let matches = |p: &String| params.iter().any(|x| param_match(p, &x.name));
    f.free.retain(matches);
    if f.free.is_empty() {
        f.free = vec!["*".into()];
    }
    f.fixed.retain(matches);
    f.mechanism = mechanism;
    f
}
