"""pytest suite of the Python bindings: needs nothing outside the repository (data are simulated;
the comparison with the command line runs when a built `kinecal` binary is found)."""
import html
import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import kinecal

ROOT = Path(__file__).resolve().parents[2]


def kinecal_binary():
    for p in [os.environ.get("KINECAL_BIN"), ROOT / "target/release/kinecal", ROOT / "target/debug/kinecal", shutil.which("kinecal")]:
        if p and Path(p).is_file():
            return str(p)
    return None


def test_builtin_models_and_kinematics_round_trip():
    m = kinecal.Model.load("irb120")
    assert m.name == "irb120" and len(m.inputs) == 6 and m.input_units == ["angle"] * 6
    rng = np.random.default_rng(1)
    q = rng.uniform(-1.5, 1.5, size=(50, 6))
    poses = m.forward(q)
    assert poses.shape == (50, 4, 4)
    np.testing.assert_allclose(poses[:, 3, :], np.tile([0, 0, 0, 1.0], (50, 1)))
    back = m.inverse(poses, seeds=q + 0.01)
    np.testing.assert_allclose(m.forward(back), poses, atol=1e-8)


def test_parallel_model_forward_inverse():
    m = kinecal.Model.load("pm5")
    truth, data = kinecal.simulate(m, 5, seed=3, error_mm=0.0, error_deg=0.0)
    q = data.q
    poses = m.forward(q)
    np.testing.assert_allclose(m.inverse(poses), q, atol=1e-7)


def test_model_file_text_round_trip():
    m = kinecal.Model.load("stewart")
    back = kinecal.Model.from_toml(m.to_toml(), "stewart.toml")
    q = kinecal.simulate(m, 3, seed=2, error_mm=0, error_deg=0)[1].q
    np.testing.assert_allclose(back.forward(q), m.forward(q), atol=1e-9)


def test_controller_files_round_trip():
    m = kinecal.Model.load("stewart")
    text, projection = m.to_controller("linuxcnc-hexapod")
    p = json.loads(projection)
    assert p["position_max_mm"] < 1e-8 and p["not_represented"] == []
    back = kinecal.Model.from_controller(text, "linuxcnc-hexapod", "hex.hal")
    assert back.to_controller("linuxcnc-hexapod")[0] == text
    with pytest.raises(kinecal.KinecalError, match=r"^bad\.hal:6: "):
        kinecal.Model.from_controller(text.replace("setp genhexkins.base.0.x", "setp genhexkins.base.0.q"), "linuxcnc-hexapod", "bad.hal")


def test_noise_free_calibration_recovers_the_prototype():
    m = kinecal.Model.load("irb120")
    truth, data = kinecal.simulate(m, 40, seed=5)
    _, valid = kinecal.simulate(m, 20, seed=6)
    cal = kinecal.calibrate(m, data, noise_mm=0.02, noise_deg=0.01)
    assert cal.converged and cal.verdict == "calibrated"
    q = valid.q
    np.testing.assert_allclose(cal.model.forward(q)[:, :3, 3], truth.forward(q)[:, :3, 3], atol=1e-8)
    names = [p["name"] for p in cal.parameters]
    assert "mx" in names and all(set(p) >= {"value", "std_dev", "unit", "status"} for p in cal.parameters)


def test_kind_noise_is_stated_per_kind_and_checked():
    m = kinecal.Model.load("irb120")
    _, data = kinecal.simulate(m, 40, seed=5)
    cal = kinecal.calibrate(m, data, kind_noise=["probe=0.005", "seat=0.01"], starts=1)
    assert "probe = 0.005" in cal.model.to_toml() and "seat = 0.01" in cal.model.to_toml()
    with pytest.raises(ValueError, match="KIND=MM"):
        kinecal.calibrate(m, data, kind_noise=["touch=1"])
    with pytest.raises(ValueError, match="> 0"):
        kinecal.calibrate(m, data, kind_noise=["probe=0"])


def test_noisy_calibration_validates_at_noise_level():
    m = kinecal.Model.load("irb120")
    truth, data = kinecal.simulate(m, 60, seed=7, noise_mm=0.02, noise_deg=0.01)
    before = kinecal.validate(m, data)
    cal = kinecal.calibrate(m, data, noise_mm=0.02, noise_deg=0.01, frames="model")
    after = kinecal.validate(cal.model, data)
    assert after.stats["position_rms_mm"] < 0.05 < before.stats["position_rms_mm"]
    assert after.position.shape == (60,) and after.orientation is not None
    ident = kinecal.identifiability(m, data)
    assert ident["rank"] == 30 and len(ident["redundant"]) == 12
    assert "<html" in cal.report_html()[:200].lower()
    inline = cal._repr_html_()
    assert inline.startswith("<iframe srcdoc=") and "&lt;canvas id=&quot;view3d&quot;" in inline
    assert html.unescape(inline.split('srcdoc="', 1)[1].split('" style=', 1)[0]) == cal.report_html()


def test_data_from_arrays_equals_data_from_the_simulation():
    m = kinecal.Model.load("irb120")
    truth, data = kinecal.simulate(m, 30, seed=9)
    poses = truth.forward(data.q)
    arrays = kinecal.Data.from_arrays(m, data.q, poses[:, :3, 3], poses[:, :3, :3], ids=list(range(100, 130)))
    assert len(arrays) == 30 and arrays.ids[0] == 100
    a = kinecal.calibrate(m, arrays, frames="model", starts=1)
    b = kinecal.calibrate(m, data, frames="model", starts=1)
    np.testing.assert_allclose([p["value"] for p in a.parameters], [p["value"] for p in b.parameters], atol=1e-9)


def test_compensation_reaches_the_targets_on_the_calibrated_model():
    m = kinecal.Model.load("irb120")
    truth, data = kinecal.simulate(m, 40, seed=11)
    cal = kinecal.calibrate(m, data, frames="model")
    targets = truth.forward(data.q[:5])
    q = kinecal.compensate(cal.model, targets)
    np.testing.assert_allclose(truth.forward(q), targets, atol=1e-6)


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda m: m.forward(np.zeros((3, 5))), "shape (n, 6)"),
        (lambda m: m.forward(np.full((2, 6), np.nan)), "NaN"),
        (lambda m: kinecal.Model.load("no-such-robot"), "no-such-robot"),
        (lambda m: kinecal.Model.from_toml('name = "x"\n[mechanism]\nkind = "delta"\n'), "delta"),
        (lambda m: kinecal.simulate(m, 5, measure="laser"), "laser"),
        (lambda m: kinecal.calibrate(m, kinecal.simulate(m, 2)[1]), "pose"),
        (lambda m: m.inverse(np.zeros((2, 3, 3))), "(n, 4, 4)"),
        (lambda m: kinecal.compensate(m, np.eye(4)[None] * 2), "rotation"),
    ],
)
def test_bad_input_raises_a_clear_exception(call, message):
    m = kinecal.Model.load("irb120")
    with pytest.raises(kinecal.KinecalError) as e:
        call(m)
    assert message in str(e.value)
    assert "\n" not in str(e.value)


def test_python_equals_the_command_line_on_the_quickstart_files(tmp_path):
    exe = kinecal_binary()
    if exe is None:
        pytest.skip("no kinecal binary built (cargo build) next to the package")
    run = lambda *a: subprocess.run([exe, *a], cwd=tmp_path, check=True, capture_output=True, text=True).stdout
    run("model", "export", "pm5", "--out", "pm5.toml")
    run("simulate", "pm5.toml", "--poses", "30", "--seed", "1", "--error-mm", "0.2", "--error-deg", "0.02",
        "--noise-mm", "0.02", "--noise-deg", "0.02", "--out", "measurements.csv", "--truth", "truth.toml",
        "--validation-poses", "20", "--validation-out", "validation.csv")
    cli = json.loads(run("identify", "pm5.toml", "measurements.csv", "--frames", "model", "--validation", "validation.csv",
                         "--noise-mm", "0.02", "--noise-deg", "0.02", "--out", "cal.toml", "--json"))
    m = kinecal.Model.load(str(tmp_path / "pm5.toml"))
    cal = kinecal.calibrate(m, kinecal.Data.read(str(tmp_path / "measurements.csv"), m),
                            kinecal.Data.read(str(tmp_path / "validation.csv"), m),
                            noise_mm=0.02, noise_deg=0.02, frames="model")
    assert [p["name"] for p in cal.parameters] == [p["name"] for p in cli["params"]]
    for a, b in zip(cal.parameters, cli["params"]):
        assert abs(a["value"] - b["value"]) <= 1e-12, (a, b)
        assert abs(a["std_dev"] - b["std_dev"]) <= 1e-12, (a, b)
    assert abs(cal.sigma0 - cli["sigma0"]) <= 1e-12
    assert abs(cal.validation["position_rms_mm"] - cli["validation"]["after_stats"]["position_rms_mm"]) <= 1e-12


def test_held_out_placements_are_their_own_artifacts_as_on_the_command_line(tmp_path):
    """Real seat data (tests/data/mukca-panda): three placements identify, the fourth is the
    validation set with its sockets numbered 0 and 1 like the first placement's; calibrate()
    judges them as held-out artifacts of their own (Calibration.held_out), with the figures
    `kinecal validate` gives on the written model, and the warnings of a narrowed URDF limit."""
    exe = kinecal_binary()
    if exe is None:
        pytest.skip("no kinecal binary built (cargo build) next to the package")
    run = lambda *a: subprocess.run([exe, *a], cwd=tmp_path, check=True, capture_output=True, text=True).stdout
    data = ROOT / "tests/data/mukca-panda"
    urdf = (data / "panda.urdf").read_text().replace('lower="-3.0718"', 'lower="-2.8900"', 1)
    (tmp_path / "panda.urdf").write_text(urdf)
    run("model", "import", "panda.urdf", "--tip", "ball_link", "-o", "panda.toml")
    def join(places, out):
        seats = [a for p in places for s in (0, 1) for a in ("--seat", str(data / p / f"socket_{s}.csv"))]
        run("data", "join", "panda.toml", *seats, "--angles", "rad", "--out", out)
    join(["back_left", "front_right", "high"], "ident.csv")
    join(["mid_left"], "held.csv")
    m = kinecal.Model.load(str(tmp_path / "panda.toml"))
    ident = kinecal.Data.read(str(tmp_path / "ident.csv"), m)
    assert len(ident.warnings) == 1 and "panda_joint4: " in ident.warnings[0] and "vendor's software limits" in ident.warnings[0]
    cal = kinecal.calibrate(m, ident, kinecal.Data.read(str(tmp_path / "held.csv"), m),
                            seat_distances=["0:1:50", "2:3:50", "4:5:50"], validation_seat_distances=["0:1:50"])
    h = cal.held_out
    assert cal.validation is None and h["rows"] == 63 and cal.verdict != "failed"
    (tmp_path / "cal.toml").write_text(cal.model.to_toml())
    cli = json.loads(run("validate", "cal.toml", "held.csv", "--seat-distance", "0:1:50", "--json"))["instrument"]
    for mine, theirs in zip(h["calibrated"]["seats"], cli["seats"]):
        assert abs(mine["rms_mm"] - theirs["rms_mm"]) <= 1e-9
    assert abs(h["calibrated"]["distances"][0][3] - cli["distances"][0][3]) <= 1e-9
    assert h["before_rms_mm"] > 3.0 and h["after_rms_mm"] < 0.5
    # One held-out socket checks the calibration: the seat placed anew by its rows, still
    # calibrated; with joint 2's reading moved by 0.2°, drifted and that offset named.
    run("data", "join", "panda.toml", "--seat", str(data / "mid_left" / "socket_0.csv"), "--angles", "rad", "--out", "seat.csv")
    seat = kinecal.check(cal, kinecal.Data.read(str(tmp_path / "seat.csv"), m))
    assert not seat["drifted"] and seat["poses"][0]["artifact"]["name"] == "seat 0"
    lines = (tmp_path / "seat.csv").read_text().splitlines()
    column = lines[0].split(",").index("panda_joint2_deg")
    moved = [lines[0]]
    for line in lines[1:]:
        cells = line.split(",")
        cells[column] = repr(float(cells[column]) + 0.2)
        moved.append(",".join(cells))
    (tmp_path / "moved.csv").write_text("\n".join(moved) + "\n")
    drift = kinecal.check(cal, kinecal.Data.read(str(tmp_path / "moved.csv"), m))
    assert drift["drifted"] and drift["pattern"]["name"] == "joint panda_joint2 offset", drift["pattern"]


def test_plan_chooses_a_well_conditioned_set():
    m = kinecal.Model.load("irb120")
    rng = np.random.default_rng(3)
    cands = rng.uniform(-1.5, 1.5, size=(400, 6))
    chosen, ix = kinecal.plan(m, cands, 15, criterion="d")
    assert len(chosen) == 15 == len(set(chosen)) and max(chosen) < 400
    assert ix["identifiable_parameters"] == 30 and np.isfinite(ix["log_det"])
    with pytest.raises(kinecal.KinecalError, match="fewer than the 500"):
        kinecal.plan(m, cands, 500)
    with pytest.raises(kinecal.KinecalError, match="criterion"):
        kinecal.plan(m, cands, 10, criterion="o9")


def test_joint_terms_model_takes_joint_columns_alone():
    text = kinecal.Model.load("irb120").to_toml().replace(
        "\n[calibration]",
        '\n[mechanism.joint_terms]\nbacklash = ["q2", "q3"]\ngravity = ["q2"]\n\n[calibration]',
    )
    m = kinecal.Model.from_toml(text, "terms.toml")
    assert m.inputs[-2:] == ["dir_q2", "dir_q3"]
    truth, data = kinecal.simulate(m, 60, seed=4, noise_mm=0.0, noise_deg=0.0)
    assert data.q.shape[1] == 8
    # The joint columns alone: the approach directions come from the row order, as the
    # simulation's (it visits its configurations in order).
    poses = truth.forward(data.q[:, :6])
    np.testing.assert_allclose(poses, truth.forward(data.q), atol=1e-12)
    arrays = kinecal.Data.from_arrays(m, data.q[:, :6], poses[:, :3, 3], poses[:, :3, :3])
    cal = kinecal.calibrate(m, arrays, noise_mm=0.01, noise_deg=0.001)
    assert cal.converged
    np.testing.assert_allclose(cal.model.forward(data.q)[:, :3, 3], poses[:, :3, 3], atol=1e-8)


@pytest.mark.parametrize("name", ["pm5-limbs", "t3r1-chain"])
def test_limbs_machines_with_sub_loops_and_parallelograms(name):
    # pm5 with its sub-closed loops as limbs, and a 3T1R chain with parallelogram joints: loaded,
    # simulated and calibrated through the bindings like any model; noise-free recovery.
    m = kinecal.Model.load(name)
    truth, data = kinecal.simulate(m, 40, seed=4, error_mm=0.2, error_deg=0.02)
    _, valid = kinecal.simulate(m, 10, seed=5, error_mm=0.0, error_deg=0.0)
    cal = kinecal.calibrate(m, data, noise_mm=0.01, noise_deg=0.005, frames="model")
    assert cal.converged
    q = valid.q
    np.testing.assert_allclose(cal.model.forward(q)[:, :3, 3], truth.forward(q)[:, :3, 3], atol=1e-7)


def test_observed_joints_of_the_3t1r_machine():
    # The whole 3T1R machine: four sliders, five encoders read as observations. Simulated with
    # their readings, rebuilt from arrays, calibrated; without readings the encoder zeros are
    # not identified.
    m = kinecal.Model.load("t3r1")
    assert m.inputs == ["s1", "s3", "s2", "s4"]
    assert m.observed == ["u1", "r1", "u3", "u2", "u4"]
    truth, data = kinecal.simulate(m, 30, seed=4, error_mm=0.2, error_deg=0.02)
    assert data.joints.shape == (30, 5)
    _, valid = kinecal.simulate(m, 10, seed=5, error_mm=0.0, error_deg=0.0)
    cal = kinecal.calibrate(m, data, noise_mm=0.01, noise_deg=0.005, encoder_noise_deg=0.005, frames="model")
    assert cal.converged
    assert cal.report["rank"] == 43
    q = valid.q
    np.testing.assert_allclose(cal.model.forward(q)[:, :3, 3], truth.forward(q)[:, :3, 3], atol=1e-7)
    rot = truth.forward(data.q)[:, :3, :3]
    again = kinecal.Data.from_arrays(m, data.q, data.positions, rot, joints=data.joints)
    np.testing.assert_allclose(again.joints, data.joints)
    poses_only = kinecal.Data.from_arrays(m, data.q, data.positions, rot)
    assert poses_only.joints.shape == (30, 0)
    assert kinecal.calibrate(m, poses_only, frames="model").report["rank"] == 38
    with pytest.raises(ValueError, match="encoder_noise_deg"):
        kinecal.calibrate(m, data, encoder_noise_deg=0.0)


def test_plan_sampled_writes_the_command_line_s_plan(tmp_path):
    """Python's plan_sampled and `kinecal plan` are one library call: the same CSV, byte for byte."""
    m = kinecal.Model.load("irb120")
    box = dict(x_mm=(250, 450), y_mm=(-200, 200), z_mm=(300, 600), alpha_deg=(-20, 20), beta_deg=(-20, 20), gamma_deg=(-30, 30))
    p = kinecal.plan_sampled(m, 20, candidates=3000, **box)
    assert len(p.chosen) == 20 and p.generation["sampled"] == 3000
    assert p.indices["o2"] > 0 and p.summary["mechanism"] == "irb120"
    p.save(str(tmp_path / "py.csv"))
    bin_ = kinecal_binary()
    if bin_:
        args = [bin_, "plan", "--model", "irb120", "-n", "20", "--candidates", "3000", "-o", str(tmp_path / "cli.csv")]
        for k, (a, b) in box.items():
            args += [f"--{k.replace('_', '-')}", f"{a},{b}"]
        subprocess.run(args, check=True, capture_output=True)
        assert (tmp_path / "cli.csv").read_bytes() == (tmp_path / "py.csv").read_bytes()
    # No range at all: the arm's inputs within their limits.
    j = kinecal.plan_sampled(m, 10, candidates=100)
    assert len(j.chosen) == 10 and j.generation["sampled"] == 100
    with pytest.raises(kinecal.KinecalError, match="paper's grid"):
        kinecal.plan_sampled(m, 10, grid="paper", **box)


def test_assess_gives_the_iso_9283_figures(tmp_path):
    """The hand-worked example of docs/assess.md: AP_P = sqrt(17)/3, RP_l = 2.25707 mm."""
    (tmp_path / "c.csv").write_text("pose,x_mm,y_mm,z_mm\n1,0,0,0\n2,10,0,0\n")
    (tmp_path / "a.csv").write_text(
        "pose,cycle,x_mm,y_mm,z_mm\n1,1,1,0,0\n1,2,1,2,0\n1,3,1,0,2\n2,1,10.1,0,0\n2,2,9.9,0,0\n2,3,10,0,0\n"
    )
    r = kinecal.assess(str(tmp_path / "c.csv"), str(tmp_path / "a.csv"), [(1, 2)])
    assert abs(r["poses"][0]["ap_p"] - 17 ** 0.5 / 3) < 1e-12
    assert abs(r["poses"][0]["rp_l"] - 2.25707) < 1e-5
    assert r["distances"][0]["cycles"] == 3
    (tmp_path / "u.csv").write_text("pose,cycle,x_mm,y_mm,z_mm\n1,1,0,0,0\n1,2,0,0,0\n3,1,1,0,0\n")
    with pytest.raises(kinecal.KinecalError, match="test pose 3 is not among the commanded poses"):
        kinecal.assess(str(tmp_path / "c.csv"), str(tmp_path / "u.csv"))


def test_assess_refuses_implausible_attained_poses_unless_forced(tmp_path):
    """Attained poses 100 mm from their commands (another run's file, metres for mm) are refused
    naming the pose and the figure, as kinecal assess refuses them; force=True assesses them."""
    (tmp_path / "c.csv").write_text("pose,x_mm,y_mm,z_mm\n1,0,0,0\n2,10,0,0\n")
    (tmp_path / "far.csv").write_text(
        "pose,cycle,x_mm,y_mm,z_mm\n1,1,0,0,0\n1,2,0,0,0\n2,1,110,0,0\n2,2,110,0,0\n"
    )
    with pytest.raises(kinecal.KinecalError, match="test pose 2 is attained 100.000 mm from where it was commanded"):
        kinecal.assess(str(tmp_path / "c.csv"), str(tmp_path / "far.csv"))
    r = kinecal.assess(str(tmp_path / "c.csv"), str(tmp_path / "far.csv"), force=True)
    assert abs(r["poses"][1]["ap_p"] - 100.0) < 1e-9


def test_assess_circle_and_plan_iso9283(tmp_path):
    """ISO 230-4 by hand (an ellipse of radii 100.01 / 99.99: G = 0.02, F = +-0.01) and the ISO 9283
    test poses in a region of pm5 that is all reachable (the cube is the region's, P1 its centre)."""
    (tmp_path / "bb.csv").write_text("angle_deg,deviation_mm\n0,0.01\n90,-0.01\n180,0.01\n270,-0.01\n")
    t = kinecal.assess_circle(str(tmp_path / "bb.csv"), 100.0)
    assert abs(t["circular_deviation_g_mm"] - 0.02) < 1e-9
    assert abs(t["radial_deviation_f_max_mm"] - 0.01) < 1e-9
    summary, commands = kinecal.plan_iso9283(
        kinecal.Model.load("pm5"), (0.0, 0.0, 0.0), ((-30.0, -30.0, 470.0), (30.0, 30.0, 530.0))
    )
    assert abs(summary["side_mm"] - 60.0) < 1e-9
    assert summary["poses"][0]["position_mm"] == [0.0, 0.0, 500.0]
    assert commands.shape[0] == 5


def test_plan_instrument_gives_each_seat_its_rows():
    """Seat orientations planned on the nominal (``kinecal plan --seats``): the rows asked for, each
    seat its minimum, the same seed the same plan; a negative bar is refused."""
    m = kinecal.Model.load("irb120")
    seats = [(400, 0, 300), (450, 100, 250), (350, -100, 350), (420, 50, 400)]
    opts = dict(tool_mm=[15, -10, 120], candidates_per_point=20, tilt_deg=35, min_per_point=3, seed=3,
                reference=list(np.radians([0, 20, 11.5, 0, 57, 0])))
    q, point_of, summary = kinecal.plan_instrument(m, seats, 24, **opts)
    assert q.shape == (24, 6) and len(point_of) == 24 and summary["rows"] == 24
    assert all(point_of.count(k) >= 3 for k in range(4)), point_of
    assert summary["instrument"] == "seat" and np.isfinite(summary["indices"]["log_det"])
    again, _, _ = kinecal.plan_instrument(m, seats, 24, **opts)
    np.testing.assert_array_equal(q, again)
    with pytest.raises(kinecal.KinecalError, match="must be positive"):
        kinecal.plan_instrument(m, seats[:1], 8, ballbar_mm=-100.0)


def test_touches_are_simulated_planned_and_calibrated():
    m = kinecal.Model.load("irb120")
    spheres = [[300.0, 0.0, 300.0], [350.0, -150.0, 250.0], [350.0, 150.0, 250.0]]
    truth, data = kinecal.simulate_touches(
        m, probe_radius_mm=1.5, spheres=spheres, sphere_diameter_mm=25.4, per_artifact=30, tool_mm=[15.0, -10.0, 120.0], seed=3
    )
    cal = kinecal.calibrate(m, data, starts=1)
    assert cal.verdict != "failed" and cal.sigma0 < 1e-3, cal.reasons
    # Judged as spheres: each placed by the model's probe centres, its length residuals.
    _, held = kinecal.simulate_touches(
        m, probe_radius_mm=1.5, spheres=spheres, sphere_diameter_mm=25.4, per_artifact=8, tool_mm=[15.0, -10.0, 120.0], seed=3
    )
    judged = kinecal.validate_instrument(cal.model, held)
    assert [p["kind"] for p in judged["pivots"]] == ["Sphere"] * 3
    assert all(p["rms_mm"] < 1e-6 for p in judged["pivots"]), judged
    nominal = kinecal.validate_instrument(m, held)
    assert all(p["rms_mm"] > 1e-3 for p in nominal["pivots"]), nominal
    plan, summary = kinecal.plan_touches(
        m, 48, probe_radius_mm=1.5, cube=[350.0, 0.0, 250.0], cube_edge_mm=100.0, cube_rotation_deg=[5.0, 10.0, 15.0], tool_mm=[15.0, -10.0, 120.0]
    )
    assert summary["rows"] == 48 and summary["rows_per_artifact"] == {"cube 0": 48}
    with pytest.raises(kinecal.KinecalError, match="metres"):
        kinecal.simulate_touches(m, probe_radius_mm=1.5, spheres=spheres, sphere_diameter_mm=0.0254)
    with pytest.raises(kinecal.KinecalError, match="one kind"):
        kinecal.simulate_touches(m, probe_radius_mm=1.5, spheres=spheres, sphere_diameter_mm=25.4, cube=[0.0, 0.0, 0.0], cube_edge_mm=100.0)


def test_filter_program_gcode_arc_and_long_move(tmp_path):
    """``kinecal.filter_program`` on 5-axis G-code for pm5: the arc linearised, the long move
    split to 0.01 mm, and a corrected block sent to the nominal controller reaching its original
    tip on the calibrated model."""
    nominal = kinecal.Model.load("pm5")
    truth, data = kinecal.simulate(nominal, 40, seed=6, error_mm=0.2, error_deg=0.02, noise_mm=0.002, noise_deg=0.002)
    cal = kinecal.calibrate(nominal, data, noise_mm=0.002, noise_deg=0.002, frames="model").model
    prog = tmp_path / "head.nc"
    text = "G21 G90 ; head\nG0 X-20 Y-20 Z380 A0 B0\nG1 X20 Y20 Z420 A2 B-1 F500\nG2 X20 Y10 I0 J-5 ; arc\nM30\n"
    prog.write_text(text)
    out = tmp_path / "head_cal.nc"
    r = kinecal.filter_program(cal, nominal, str(prog), str(out), max_deviation_mm=0.01)
    assert out.read_text() == r["text"]
    p = r["paths"]
    assert p["arcs"] == 1 and p["arc_chords"] >= 2 and p["largest_chord_error_mm"] <= 0.005
    assert p["largest_deviation_mm"] <= 0.01
    assert "G2 " not in r["text"] and r["text"].count("\n") == text.count("\n") + p["added_points"] + p["arc_chords"] - 1
    assert max(t["before_mm"] for t in r["targets"]) > 0.05
    assert max(t["after_mm"] for t in r["targets"]) < 1e-3
    # The G0 block as filtered, sent to the nominal controller, read here: X Y Z, A B about x then y.
    words = dict((w[0], float(w[1:])) for w in r["text"].splitlines()[1].split()[1:])
    a, b = np.radians(words["A"]), np.radians(words["B"])
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    pose = np.eye(4)
    pose[:3, :3] = rx @ ry
    pose[:3, 3] = [words["X"], words["Y"], words["Z"]]
    q = nominal.inverse(pose[None])
    reached = cal.forward(q)[0]
    assert np.linalg.norm(reached[:3, 3] - [-20, -20, 380]) < 2e-3
    with pytest.raises(kinecal.KinecalError):
        kinecal.filter_program(cal, nominal, str(prog), str(prog))


def test_predict_accuracy_of_a_calibrated_model():
    m = kinecal.Model.load("irb120")
    truth, data = kinecal.simulate(m, 60, seed=7, noise_mm=0.02, noise_deg=0.02)
    cal = kinecal.calibrate(m, data, noise_mm=0.02, noise_deg=0.02)
    q = kinecal.simulate(m, 20, seed=8)[1].q
    acc = kinecal.predict_accuracy(cal.model, q)
    assert acc["position_mm"].shape == (20,) and acc["positions"].shape == (20, 3)
    # The calibration leaves tens of µm at most; one measurement adds √3 · 20 µm.
    assert (acc["position_mm"] > 0).all() and (acc["position_mm"] < 0.1).all()
    assert abs(acc["noise_position_mm"] - 3**0.5 * 0.02) < 1e-12
    # The command line's figures from the same model file.
    back = kinecal.Model.from_toml(cal.model.to_toml(), "cal.toml")
    again = kinecal.predict_accuracy(back, q)
    assert np.allclose(again["position_mm"], acc["position_mm"], rtol=1e-9)
    with pytest.raises(kinecal.KinecalError, match="no \\[covariance\\]"):
        kinecal.predict_accuracy(m, q)


def test_plan_check_chooses_configurations_that_name_drifts_apart():
    m = kinecal.Model.load("irb120")
    truth, data = kinecal.simulate(m, 60, seed=7, noise_mm=0.02, noise_deg=0.02)
    cal = kinecal.calibrate(m, data, noise_mm=0.02, noise_deg=0.02)
    q = kinecal.simulate(m, 200, seed=8)[1].q
    plan = kinecal.plan_check(cal, q, n=5)
    chosen = plan["selected"]
    assert len(chosen) == 5 and len(set(chosen)) == 5 and all(0 <= i < 200 for i in chosen)
    assert plan["wrong_names"] < plan["wrong_names_unplanned"]
    # The calibrated model file plans the same as the calibration in memory.
    back = kinecal.Model.from_toml(cal.model.to_toml(), "cal.toml")
    assert kinecal.plan_check(back, q, n=5)["selected"] == chosen
    with pytest.raises(kinecal.KinecalError, match="configurations"):
        kinecal.plan_check(cal, q[:, :5])


def test_an_update_sets_a_pose_off_aside_and_its_model_checks_again():
    m = kinecal.Model.load("irb120")
    truth, data = kinecal.simulate(m, 60, seed=7, noise_mm=0.02, noise_deg=0.02)
    cal = kinecal.calibrate(m, data, noise_mm=0.02, noise_deg=0.02)
    q = kinecal.simulate(m, 10, seed=9)[1].q
    poses = truth.forward(q)
    rng = np.random.default_rng(3)
    positions = poses[:, :3, 3] + rng.normal(0.0, 0.02, (10, 3))
    # A blunder: the fifth pose measured 3 mm off.
    positions[4, 0] += 3.0
    new = kinecal.Data.from_arrays(m, q, positions, poses[:, :3, :3])
    up = kinecal.calibrate(m, new, prior=cal)
    assert up.passed and up.released == []
    assert up.set_aside["index"] == 4 and abs(up.set_aside["position_mm"] - 3.0) < 0.2
    # The updated model carries its covariance: it is checked as a calibrated model file is.
    again = kinecal.check(up.model, new)
    assert not again["drifted"] and again["one_pose"]["index"] == 4
