//! Hostile but realistic input (issue: never hang, never destroy, never pass a failed result):
//! each case answers at once with one clear message.
use kinecal::design::{CandidateJacobians, SelectOptions};
use kinecal::io::data_file::{data_from_table, InputColumns};
use kinecal::io::model_file::ModelFile;
use kinecal::io::table::parse_table;
use kinecal::model::builtin;
use kinecal::Mechanism;
use std::path::Path;

fn irb120_file() -> ModelFile {
    builtin::model_file("irb120").unwrap()
}

fn read(text: &str) -> Result<kinecal::io::data_file::DataSet, String> {
    let path = Path::new("d.csv");
    let table = parse_table(path, text).map_err(|e| e.to_string())?;
    data_from_table(&table, &irb120_file().inputs(), InputColumns::Required).map_err(|e| e.to_string())
}

const HEADER: &str = "id,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,x_mm,y_mm,z_mm";

#[test]
fn duplicate_ids_name_both_lines() {
    let e = read(&format!("{HEADER}\n1,0,0,0,0,30,0,1,2,3\n1,0,0,0,0,30,0,1,2,3\n")).unwrap_err();
    assert_eq!(e, "d.csv:3: id 1 appears twice (first on line 2); every pose needs its own id");
}

#[test]
fn joint_values_outside_the_limits_are_refused() {
    let e = read(&format!("{HEADER}\n1,500,0,0,0,30,0,1,2,3\n")).unwrap_err();
    assert!(e.starts_with("d.csv:2: q1: 500.0000 deg is outside the model's limits"), "{e}");
}

#[test]
fn a_header_only_file_is_refused() {
    let e = read(&format!("{HEADER}\n")).unwrap_err();
    assert!(e.contains("no data rows"), "{e}");
}

#[test]
fn extra_array_elements_in_a_model_file_are_refused() {
    let text = builtin::model_file("pm5").unwrap().to_toml().unwrap();
    let line = text
        .lines()
        .position(|l| l.trim_start().starts_with("c = ["))
        .expect("a 'c = [..]' line");
    let bad: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| if i == line { l.replacen(']', ", 5]", 1) } else { l.to_string() })
        .collect();
    let e = ModelFile::load_str(Path::new("m.toml"), &bad.join("\n")).unwrap_err().to_string();
    assert!(e.starts_with(&format!("m.toml:{}: ", line + 1)), "{e}");
    assert!(e.ends_with(".c: expected 3 values, found 4"), "{e}");
}

#[test]
fn extreme_geometry_fails_fast_instead_of_hanging() {
    // 1e15 mm, 1e-308 and 1e300 in closed-loop geometries: loading, forward kinematics and the
    // identification Jacobian answer (a clear error, or finite values), never spin inside an SVD
    // of NaN.
    for kind in ["stewart", "pm5"] {
        let text = builtin::model_file(kind).unwrap().to_toml().unwrap();
        let line = text
            .lines()
            .find(|l| l.trim_start().starts_with("base = [") || l.trim_start().starts_with("c = ["))
            .unwrap();
        let first = line.split('[').nth(1).unwrap().split(',').next().unwrap();
        for extreme in ["1e15", "1e-308", "1e300"] {
            let bad = text.replacen(line, &line.replacen(first, extreme, 1), 1);
            let file = match ModelFile::load_str(Path::new("m.toml"), &bad) {
                Ok(f) => f,
                Err(e) => {
                    assert!(e.to_string().starts_with("m.toml:"), "{e}");
                    continue;
                }
            };
            let m = file.build();
            let q = vec![1.0; m.input_names().len()];
            if let Ok((pose, jac)) = m.forward_with_jacobian(&q) {
                assert!(pose.translation.vector.iter().all(|v| v.is_finite()), "{kind} {extreme}");
                assert!(jac.iter().all(|v| v.is_finite()), "{kind} {extreme}");
            }
        }
    }
}

#[test]
fn plan_options_that_cannot_work_are_refused() {
    let blocks = CandidateJacobians::from_raw(
        6,
        (0..12).collect(),
        (0..6 * 12 * 4).map(|i| ((i * 37) % 11) as f64 - 5.0).collect(),
    )
    .unwrap();
    let mut opts = SelectOptions {
        n: 1,
        ..SelectOptions::default()
    };
    let e = kinecal::design::select::greedy(&blocks, &opts, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("choose at least 2"), "{e}");
    opts.n = 2;
    opts.pool = 0;
    let e = kinecal::design::select::sffs(&blocks, &opts, &mut |_| {}).unwrap_err().to_string();
    assert!(e.contains("pool must be at least 1"), "{e}");
}
