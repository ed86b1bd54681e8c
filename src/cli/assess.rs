//! `kinecal assess --commanded C ATTAINED [AFTER]`: ISO 9283 pose accuracy and repeatability
//! (and distance accuracy) of measured test runs, before and after calibration side by side;
//! `--circle FILE --radius-mm R`: an ISO 230-4 circular test; `--report` an HTML page of both.
use anyhow::Context;
use clap::Args;
use kinecal::assess::{iso230_4, iso230_4_both, iso9283, AssessError, BidirectionalTest, CircularTest, Iso9283, Plane};
use kinecal::io::output::Outputs;
use kinecal::io::test_poses::{read_attained, read_circle, read_commanded};
use std::path::{Path, PathBuf};

/// Arguments of `kinecal assess`.
#[derive(Args, Debug)]
pub struct AssessArgs {
    /// The commanded test poses (CSV: pose,x_mm,y_mm,z_mm[,roll_deg,pitch_deg,yaw_deg]; a file of
    /// `plan --iso9283` or a targets file of `compensate`, its `id` the pose).
    #[arg(long)]
    pub commanded: Option<PathBuf>,
    /// The attained poses, measured (CSV: pose,cycle,x_mm,y_mm,z_mm[,roll_deg,pitch_deg,yaw_deg]),
    /// in the same frame as the commanded ones.
    pub attained: Option<PathBuf>,
    /// A second test run (e.g. with compensated commands), assessed beside the first.
    pub after: Option<PathBuf>,
    /// Distance accuracy between two test poses, `FROM:TO` (e.g. `2:4`); repeatable.
    #[arg(long, value_name = "FROM:TO")]
    pub distance: Vec<String>,
    /// An ISO 230-4 circular test (CSV): ballbar readings angle_deg with radius_mm or deviation_mm,
    /// or measured points x_mm,y_mm,z_mm.
    #[arg(long)]
    pub circle: Option<PathBuf>,
    /// The anticlockwise run of the same circle (same columns): `--circle` is then the clockwise
    /// run, and the figures of both directions are added (G each way, G(b) and the hysteresis H).
    #[arg(long, requires = "circle")]
    pub circle_ccw: Option<PathBuf>,
    /// The circle's nominal radius (mm).
    #[arg(long, requires = "circle", allow_hyphen_values = true)]
    pub radius_mm: Option<f64>,
    /// The circle's nominal centre "X,Y,Z" (mm), about which measured points are taken.
    #[arg(long, requires = "circle", default_value = "0,0,0", allow_hyphen_values = true, value_parser = xyz)]
    pub centre_mm: [f64; 3],
    /// The circle's plane: xy, yz or zx (angles from its first axis towards its second).
    #[arg(long, requires = "circle", default_value = "xy")]
    pub plane: Plane,
    /// Write an HTML report (the standard's tables, the circle's polar plot).
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Replace an existing report; assess attained poses even when they are beyond any plausible
    /// accuracy (more than 20 mm or 5° from their commands on average: usually files that do not
    /// belong together).
    #[arg(long)]
    pub force: bool,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// "X,Y,Z".
fn xyz(text: &str) -> Result<[f64; 3], String> {
    let v: Result<Vec<f64>, _> = text.split(',').map(|t| t.trim().parse::<f64>()).collect();
    match v.as_deref() {
        Ok(&[a, b, c]) if [a, b, c].iter().all(|x| x.is_finite()) => Ok([a, b, c]),
        _ => Err(format!("expected X,Y,Z in mm, got '{text}'")),
    }
}

/// The circular test of the arguments, if any.
fn circle(a: &AssessArgs) -> anyhow::Result<Option<CircularTest>> {
    let (Some(path), Some(radius)) = (&a.circle, a.radius_mm) else {
        return Ok(None);
    };
    let points = read_circle(path, a.plane, &a.centre_mm.into(), radius)?;
    Ok(Some(
        iso230_4(&points, radius).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?,
    ))
}

/// The circle run both ways, when `--circle-ccw` is given.
fn both_ways(a: &AssessArgs) -> anyhow::Result<Option<BidirectionalTest>> {
    let (Some(cw), Some(ccw), Some(radius)) = (&a.circle, &a.circle_ccw, a.radius_mm) else {
        return Ok(None);
    };
    let centre = a.centre_mm.into();
    let (p, q) = (
        read_circle(cw, a.plane, &centre, radius)?,
        read_circle(ccw, a.plane, &centre, radius)?,
    );
    Ok(Some(
        iso230_4_both(&p, &q, radius).map_err(|e| anyhow::anyhow!("{} / {}: {e}", cw.display(), ccw.display()))?,
    ))
}

/// The figures of one attained file, its mistakes named with the file and line (a pose commanded
/// twice with the commanded file).
fn assess_file(
    commanded: (&Path, &[kinecal::assess::TestPose]),
    path: &Path,
    distances: &[(i64, i64)],
    force: bool,
) -> anyhow::Result<Iso9283> {
    let attained = read_attained(path)?;
    let (commanded_path, commanded) = commanded;
    let figures = iso9283(commanded, &attained, distances).map_err(|e| match e {
        AssessError::UnknownPose { pose, line, known } => anyhow::anyhow!(
            "{}:{line}: test pose {pose} is not among the commanded poses ({known}): check the pose column or the commanded file",
            path.display()
        ),
        e @ AssessError::DuplicateCommand { .. } => anyhow::anyhow!("{}: {e}", commanded_path.display()),
        e => anyhow::anyhow!("{}: {e}", path.display()),
    })?;
    if !force {
        if let Some(why) = kinecal::assess::implausible(&figures) {
            anyhow::bail!("{}: {why}; --force assesses it anyway", path.display());
        }
    }
    Ok(figures)
}

/// Run the command.
pub fn run(a: AssessArgs) -> anyhow::Result<()> {
    let distances = a
        .distance
        .iter()
        .map(|d| {
            let (f, t) = d.split_once(':').context(format!("--distance '{d}': expected FROM:TO, e.g. 2:4"))?;
            Ok((f.trim().parse::<i64>()?, t.trim().parse::<i64>()?))
        })
        .collect::<anyhow::Result<Vec<_>>>()
        .map_err(|e: anyhow::Error| anyhow::anyhow!("{e:#}"))?;
    // Checked here rather than by clap, so that each mistake is one line.
    match (&a.commanded, &a.attained, &a.circle, a.radius_mm) {
        (Some(_), None, ..) => anyhow::bail!("--commanded: give the attained poses too (kinecal assess --commanded C ATTAINED [AFTER])"),
        (None, Some(_), ..) => anyhow::bail!("ATTAINED: give the commanded test poses too (--commanded C)"),
        (None, None, None, _) => {
            anyhow::bail!("nothing to assess: give ATTAINED with --commanded C (ISO 9283), or --circle FILE --radius-mm R (ISO 230-4)")
        }
        (_, _, Some(_), None) => anyhow::bail!("--circle: give the nominal radius too (--radius-mm R)"),
        (_, _, None, Some(_)) => anyhow::bail!("--radius-mm: give the circle's file too (--circle FILE)"),
        _ => {}
    }
    let mut outputs = Outputs::new(a.force);
    for p in a
        .commanded
        .iter()
        .chain(&a.attained)
        .chain(&a.after)
        .chain(&a.circle)
        .chain(&a.circle_ccw)
    {
        outputs.input(p);
    }
    if let Some(r) = &a.report {
        outputs.output(r)?;
    }
    let runs: Vec<(String, Iso9283)> = match (&a.commanded, &a.attained) {
        (Some(c), Some(first)) => {
            let commanded = read_commanded(c)?;
            std::iter::once(first)
                .chain(a.after.as_ref())
                .map(|p| Ok((p.display().to_string(), assess_file((c, &commanded), p, &distances, a.force)?)))
                .collect::<anyhow::Result<_>>()?
        }
        _ => Vec::new(),
    };
    let circular = circle(&a)?;
    let both = both_ways(&a)?;
    let circle_name = a.circle.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
    if let Some(r) = &a.report {
        let title = format!(
            "kinecal assess: {}",
            runs.iter()
                .map(|(f, _)| f.as_str())
                .chain(a.circle.as_ref().map(|_| circle_name.as_str()))
                .chain(a.circle_ccw.iter().filter_map(|p| p.to_str()))
                .collect::<Vec<_>>()
                .join(", ")
        );
        let ccw_name = a.circle_ccw.as_ref().map(|p| p.display().to_string()).unwrap_or_default();
        let html = kinecal::report::assess::assess_html(
            &title,
            &runs,
            circular.as_ref().map(|t| (circle_name.as_str(), t)),
            both.as_ref().map(|b| (ccw_name.as_str(), b)),
        );
        outputs.stage(r, html.as_bytes())?;
        outputs.commit()?;
    }
    if a.json {
        let mut v: Vec<_> = runs.iter().map(|(f, r)| serde_json::json!({"attained": f, "iso9283": r})).collect();
        match &both {
            Some(b) => v.push(serde_json::json!({"circle": circle_name, "circle_ccw": a.circle_ccw, "iso230_4_both": b})),
            None => v.extend(circular.iter().map(|t| serde_json::json!({"circle": circle_name, "iso230_4": t}))),
        }
        println!("{}", serde_json::to_string_pretty(&v)?);
        return Ok(());
    }
    if let Some(t) = &circular {
        println!(
            "ISO 230-4 circular test {circle_name} ({} plane, R {} mm, {} points): G {:.4} mm, F_max {:+.4} mm, F_min {:+.4} mm, centre offset ({:.4}, {:.4}) mm, least-squares radius {:.4} mm",
            format!("{:?}", a.plane).to_lowercase(), t.nominal_radius_mm, t.points, t.circular_deviation_g_mm, t.radial_deviation_f_max_mm, t.radial_deviation_f_min_mm,
            t.centre_offset_mm[0], t.centre_offset_mm[1], t.lsq_radius_mm
        );
    }
    if let (Some(b), Some(ccw)) = (&both, &a.circle_ccw) {
        let t = &b.anticlockwise;
        println!(
            "anticlockwise run {} ({} points): G {:.4} mm, F_max {:+.4} mm, F_min {:+.4} mm, centre offset ({:.4}, {:.4}) mm",
            ccw.display(),
            t.points,
            t.circular_deviation_g_mm,
            t.radial_deviation_f_max_mm,
            t.radial_deviation_f_min_mm,
            t.centre_offset_mm[0],
            t.centre_offset_mm[1]
        );
        println!(
            "both directions: G clockwise {:.4} mm, G anticlockwise {:.4} mm, G(b) {:.4} mm, hysteresis H {:.4} mm (common centre offset ({:.4}, {:.4}) mm)",
            b.clockwise.circular_deviation_g_mm, t.circular_deviation_g_mm, b.circular_deviation_g_both_mm, b.circular_hysteresis_h_mm,
            b.centre_offset_mm[0], b.centre_offset_mm[1]
        );
    }
    if let Some(r) = &a.report {
        println!("wrote {}", r.display());
    }
    if runs.is_empty() {
        return Ok(());
    }
    let commanded = a.commanded.as_ref().map(|c| c.display().to_string()).unwrap_or_default();
    println!("ISO 9283 pose characteristics (mm, deg), commanded poses {commanded}");
    for (file, r) in &runs {
        println!("\n{file}");
        println!(
            "{:>5} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>24} {:>24}",
            "pose", "cycles", "AP_x", "AP_y", "AP_z", "AP_P", "RP_l", "AP_a,b,c", "RP_a,b,c"
        );
        for p in &r.poses {
            let deg = |v: Option<[f64; 3]>| v.map_or("—".to_string(), |v| format!("{:.4}/{:.4}/{:.4}", v[0], v[1], v[2]));
            println!(
                "{:>5} {:>6} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>9.4} {:>24} {:>24}",
                format!("P{}", p.pose),
                p.cycles,
                p.ap_xyz[0],
                p.ap_xyz[1],
                p.ap_xyz[2],
                p.ap_p,
                p.rp_l,
                deg(p.ap_abc),
                deg(p.rp_abc)
            );
        }
        for d in &r.distances {
            let angles = match (d.ad_abc, d.rd_abc) {
                (Some(ad), Some(rd)) => format!(
                    "; AD_a,b,c {:.4}/{:.4}/{:.4} deg, RD_a,b,c ±{:.4}/{:.4}/{:.4} deg",
                    ad[0], ad[1], ad[2], rd[0], rd[1], rd[2]
                ),
                _ => String::new(),
            };
            println!(
                "distance P{}–P{} ({:.3} mm commanded, {} cycles): AD_P {:.4} (AD_x {:.4}, AD_y {:.4}, AD_z {:.4}), RD_P ±{:.4}{angles}",
                d.from, d.to, d.commanded_mm, d.cycles, d.ad_p, d.ad_xyz[0], d.ad_xyz[1], d.ad_xyz[2], d.rd_p
            );
        }
    }
    if let [(b, before), (f, after)] = &runs[..] {
        println!("\nbefore → after (AP_P / RP_l, mm): {b} → {f}");
        for (p, q) in before.poses.iter().zip(&after.poses) {
            println!(
                "P{}: AP_P {:.4} → {:.4}, RP_l {:.4} → {:.4}",
                p.pose, p.ap_p, q.ap_p, p.rp_l, q.rp_l
            );
        }
    }
    Ok(())
}
