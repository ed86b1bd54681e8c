//! ISO 9283 (`kinecal assess`) on a filtered program: pm5 calibrated from simulated data, five
//! test poses as CSV targets; the prototype run 30 cycles through the nominal controller's
//! commands for the targets as written (before), through `compensate`'s commands, and through
//! the nominal controller's commands for the filtered targets. Filtering cuts AP_P as
//! `compensate` does.
use crate::cli::{json, ok};

#[test]
fn iso9283_of_a_filtered_program_as_of_compensated_commands() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    ok(d, &["model", "export", "pm5", "--out", "pm5.toml"]);
    let errors = ["--error-mm", "0.2", "--error-deg", "0.02"];
    crate::cli::simulate(d, "pm5.toml", 40, 1, 1, 0.02, &errors);
    ok(d, &["identify", "pm5.toml", "d.csv", "--frames", "model", "--out", "cal.toml"]);
    std::fs::write(
        d.join("targets.csv"),
        "id,x_mm,y_mm,z_mm,roll_deg,pitch_deg,yaw_deg\n1,0,0,400,0,0,0\n2,-24,-24,376,0,0,0\n3,24,24,376,0,0,0\n4,24,24,424,0,0,0\n5,-24,-24,424,0,0,0\n",
    )
    .unwrap();
    // The nominal controller: the nominal model's inverse kinematics of what it is sent.
    ok(d, &["compensate", "pm5.toml", "targets.csv", "--out", "nom.csv"]);
    ok(
        d,
        &["compensate", "cal.toml", "targets.csv", "--nominal", "pm5.toml", "--out", "cmp.csv"],
    );
    let said = ok(
        d,
        &[
            "filter",
            "cal.toml",
            "targets.csv",
            "--nominal",
            "pm5.toml",
            "--out",
            "filtered.csv",
        ],
    );
    eprintln!("{said}");
    ok(d, &["compensate", "pm5.toml", "filtered.csv", "--out", "flt.csv"]);
    // CSV rows as straight moves: split to 0.003 mm, the rows added with ids of their own.
    let split = ok(
        d,
        &[
            "filter",
            "cal.toml",
            "targets.csv",
            "--nominal",
            "pm5.toml",
            "--out",
            "split.csv",
            "--max-deviation-mm",
            "0.003",
        ],
    );
    eprintln!("{split}");
    let rows = std::fs::read_to_string(d.join("split.csv")).unwrap().lines().count() - 1;
    assert!(rows > 5, "{split}");
    assert!(split.contains(&format!("{} points added to hold 0.003 mm", rows - 5)), "{split}");
    ok(d, &["compensate", "pm5.toml", "split.csv", "--out", "split-cmd.csv"]);
    for (commands, out) in [
        ("nom.csv", "before.csv"),
        ("cmp.csv", "after-cmp.csv"),
        ("flt.csv", "after-flt.csv"),
    ] {
        ok(
            d,
            &[
                "simulate",
                "t.toml",
                "--error-mm",
                "0",
                "--error-deg",
                "0",
                "--seed",
                "2",
                "--at",
                commands,
                "--cycles",
                "30",
                "--repeatability-mm",
                "0.005",
                "--out",
                out,
            ],
        );
    }
    let cmp = json(d, &["assess", "--commanded", "targets.csv", "before.csv", "after-cmp.csv"]);
    let flt = json(d, &["assess", "--commanded", "targets.csv", "before.csv", "after-flt.csv"]);
    let ap = |v: &serde_json::Value, file: usize, k: usize| v[file]["iso9283"]["poses"][k]["ap_p"].as_f64().unwrap();
    let rp = |v: &serde_json::Value, file: usize, k: usize| v[file]["iso9283"]["poses"][k]["rp_l"].as_f64().unwrap();
    for k in 0..5 {
        let (before, c, f) = (ap(&cmp, 0, k), ap(&cmp, 1, k), ap(&flt, 1, k));
        eprintln!(
            "P{}: AP_P before {before:.4}, compensate {c:.4}, filtered {f:.4} mm; RP_l {:.4} / {:.4} / {:.4} mm",
            k + 1,
            rp(&cmp, 0, k),
            rp(&cmp, 1, k),
            rp(&flt, 1, k)
        );
        assert!(before > 0.3, "P{}: AP_P before {before}", k + 1);
        assert!(f < before / 5.0, "P{}: AP_P {before} → {f}", k + 1);
        // As compensate: within 10 % or the written targets' 0.001 mm.
        assert!(
            (f - c).abs() <= 0.1 * c + 0.001,
            "P{}: filtered {f} against compensate's {c}",
            k + 1
        );
    }
}
