//! Artifact sizes a failed calibration shows to be mistaken: a sphere diameter in inches, a
//! sphere's radius in its diameter column, a probe's diameter in its radius column, a cube edge
//! in inches, a bar length in inches, centimetres or metres. Each of these leaves the touches or
//! the lengths inconsistent with the machine as stated, and the fit then fails ("a model of
//! another machine"): [`likely_mistake`] calibrates again with each size read the other way and
//! names the one with which the data calibrate, so that the user reads the cause, not its effect.
use super::{calibrate_as_stated, CalibrationOptions};
use crate::io::data_file::DataSet;
use crate::io::model_file::ModelFile;
use crate::measure::touch::Touch;
use crate::measure::Observation;
use crate::report::Status;

/// One way a size can be mistaken: what it says, and the change of a row's observation that
/// undoes it (`false` when the row has no such size).
struct Reading {
    /// The mistake, as a question, with `{}` for the stated value and the value it would be.
    what: fn(f64, f64) -> String,
    /// Undo the mistake on a row; returns the stated and the undone size when the row has it.
    undo: fn(&mut Observation) -> Option<(f64, f64)>,
}

fn sphere_diameter(o: &mut Observation, f: f64) -> Option<(f64, f64)> {
    match o {
        Observation::Touch(Touch::Sphere { diameter, .. }) => {
            let stated = *diameter;
            *diameter *= f;
            Some((stated, *diameter))
        }
        _ => None,
    }
}

fn probe_radius(o: &mut Observation, f: f64) -> Option<(f64, f64)> {
    match o {
        Observation::Touch(Touch::Sphere { probe, .. } | Touch::Plane { probe, .. } | Touch::Face { probe, .. }) if *probe > 0.0 => {
            let stated = *probe;
            *probe *= f;
            Some((stated, *probe))
        }
        _ => None,
    }
}

fn cube_edge(o: &mut Observation, f: f64) -> Option<(f64, f64)> {
    match o {
        Observation::Touch(Touch::Face { edge, .. }) => {
            let stated = *edge;
            *edge *= f;
            Some((stated, *edge))
        }
        _ => None,
    }
}

fn bar_length(o: &mut Observation, f: f64) -> Option<(f64, f64)> {
    match o {
        Observation::Distance {
            length, relative: false, ..
        } => {
            let stated = *length;
            *length *= f;
            Some((stated, *length))
        }
        _ => None,
    }
}

/// The readings tried, most likely first.
const READINGS: [Reading; 8] = [
    Reading {
        what: |s, t| format!("sphere diameter in inches? (sphere_diameter_mm {s} read as {t:.4} mm; give it in mm)"),
        undo: |o| sphere_diameter(o, 25.4),
    },
    Reading {
        what: |s, t| format!("the sphere's radius given as its diameter? (sphere_diameter_mm {s} read as {t:.4} mm)"),
        undo: |o| sphere_diameter(o, 2.0),
    },
    Reading {
        what: |s, t| format!("probe radius given as its diameter? (probe_radius_mm {s} read as {t:.4} mm)"),
        undo: |o| probe_radius(o, 0.5),
    },
    Reading {
        what: |s, t| format!("probe radius halved, as if it were a diameter? (probe_radius_mm {s} read as {t:.4} mm)"),
        undo: |o| probe_radius(o, 2.0),
    },
    Reading {
        what: |s, t| format!("cube edge in inches? (cube_edge_mm {s} read as {t:.4} mm; give it in mm)"),
        undo: |o| cube_edge(o, 25.4),
    },
    Reading {
        what: |s, t| format!("bar length in inches? (length_mm {s:.4} read as {t:.4} mm; give it in mm)"),
        undo: |o| bar_length(o, 25.4),
    },
    Reading {
        what: |s, t| format!("bar length in centimetres? (length_mm {s:.4} read as {t:.4} mm; give it in mm)"),
        undo: |o| bar_length(o, 10.0),
    },
    Reading {
        what: |s, t| format!("bar length in metres? (length_mm {s:.4} read as {t:.4} mm; give it in mm, or in metres as length_m)"),
        undo: |o| bar_length(o, 1000.0),
    },
];

/// When the calibration of `data` as stated failed (`stated_sigma0`, `why`: its σ̂₀ and first
/// reason): the artifact size read another way with which the data calibrate (a verdict other
/// than failed), as one line naming the likely mistake and both outcomes; `None` when no reading
/// does better (the failure has another cause) or the data hold no artifact sizes.
pub fn likely_mistake(model: &ModelFile, data: &DataSet, opts: &CalibrationOptions, stated_sigma0: f64, why: &str) -> Option<String> {
    let quick = CalibrationOptions {
        starts: 1,
        compare_terms: false,
        validation_seat_distances: Vec::new(),
        ..opts.clone()
    };
    for r in &READINGS {
        let mut other = data.clone();
        let mut first = None;
        for m in &mut other.measurements {
            if let Some(sizes) = (r.undo)(&mut m.obs) {
                first.get_or_insert(sizes);
            }
        }
        let Some((stated, undone)) = first else { continue };
        let Ok(cal) = calibrate_as_stated(model, &other, None, &quick) else {
            continue;
        };
        if cal.report.verdict.status != Status::Failed {
            let why = why.split(':').next().unwrap_or(why).trim();
            let sigma = if why.contains("σ̂₀") {
                String::new()
            } else {
                format!("; σ̂₀ {stated_sigma0:.3}")
            };
            return Some(format!(
                "{}: as stated the calibration fails ({why}{sigma}); read so, it calibrates (σ̂₀ {:.3}, verdict {})",
                (r.what)(stated, undone),
                cal.identification.sigma0,
                cal.report.verdict.status.as_str()
            ));
        }
    }
    None
}
