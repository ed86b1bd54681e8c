"""FIGAROH on the IRB 120 real data, beside kinecal: the same split and measurement.

Reflector 1 only (positions), identify on idx < 500, validate on idx >= 500, full geometric
calibration ("full_params"), the robot's model exported by kinecal as URDF. FIGAROH (a peer, never a
dependency) runs in a throwaway virtual environment:

    python3 -m venv /tmp/venv-fig && /tmp/venv-fig/bin/pip install figaroh
    /tmp/venv-fig/bin/python benches/peers/figaroh_irb120.py ../shared/data/irb120 target/release/kinecal

FIGAROH's calibration (1.0: `BaseCalibration`, scipy Levenberg-Marquardt on the parameters its QR
analysis keeps, numerical Jacobian) expects the measurements in the robot's base frame, so the
tracker data are first moved into it with the frames kinecal's registration found (a rigid
motion and the reflector offset from the registered start, the same start pybotics gets in
`pybotics_irb120.py`); FIGAROH then identifies the base placement, the joint placements and the
tool offset itself. Prints FIGAROH's time and held-out errors, then kinecal's on the same split.
"""
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np


def load(d):
    j = np.loadtxt(os.path.join(d, "joints_deg.csv"), delimiter=",", skiprows=1)
    s = np.loadtxt(os.path.join(d, "smr1.csv"), delimiter=",", skiprows=1)
    ok = np.all(s[:, 1:] != 0, axis=1)
    return j[ok, 0].astype(int), np.radians(j[ok, 1:]), s[ok, 1:]


def svd_register(src, dst):
    cs, cd = src.mean(0), dst.mean(0)
    u, _, vt = np.linalg.svd((dst - cd).T @ (src - cs))
    dd = np.eye(3)
    dd[2, 2] = np.sign(np.linalg.det(u @ vt))
    r = u @ dd @ vt
    return r, cd - r @ cs


def kinecal_run(kinecal, d, work):
    """kinecal's general path on the same split; returns (wall seconds, validation stats, frames)."""
    run = lambda *a: subprocess.run([kinecal, *a], check=True, capture_output=True, text=True)
    m = os.path.join(work, "irb120.toml")
    run("model", "export", "irb120", "--out", m)
    run("data", "join", m, "--joints", os.path.join(d, "joints_deg.csv"), "--angles", "deg",
        "--reflector", os.path.join(d, "smr1.csv"), "--units", "mm", "--out", os.path.join(work, "r1.csv"))
    run("data", "split", m, os.path.join(work, "r1.csv"), "--by", "below:500",
        "--out", os.path.join(work, "ident.csv"), "--rest", os.path.join(work, "valid.csv"))
    t = time.perf_counter()
    p = subprocess.run([kinecal, "identify", m, os.path.join(work, "ident.csv"), "--validation",
                        os.path.join(work, "valid.csv"), "--noise-mm", "0.05", "--out",
                        os.path.join(work, "cal.toml"), "--json"], capture_output=True, text=True)
    wall = time.perf_counter() - t
    rep = json.loads(p.stdout)
    return wall, rep


def main():
    d = sys.argv[1] if len(sys.argv) > 1 else "../shared/data/irb120"
    kinecal = sys.argv[2] if len(sys.argv) > 2 else "target/release/kinecal"
    import pinocchio as pin
    import yaml
    from figaroh.calibration.base_calibration import BaseCalibration

    work = tempfile.mkdtemp(prefix="kinecal-figaroh-")
    kwall, rep = kinecal_run(kinecal, d, work)
    ids, q, p = load(d)
    ident, valid = ids < 500, ids >= 500

    urdf = os.path.join(work, "irb120.urdf")
    subprocess.run([kinecal, "model", "export", "irb120", "--format", "urdf", "--out", urdf], check=True,
                   capture_output=True)
    robot = pin.RobotWrapper.BuildFromURDF(urdf)
    names = [robot.model.names[i] for i in range(1, robot.model.njoints)]
    flange = robot.model.getFrameId("flange")

    # The starting frames (the registration pybotics_irb120.py gives pybotics): the robot base in
    # the tracker frame and the reflector on the flange, from the nominal model and the
    # identification poses.
    def fk(qk):
        pin.framesForwardKinematics(robot.model, robot.data, qk)
        m = robot.data.oMf[flange]
        return m.rotation, m.translation * 1000.0

    flanges = [fk(qk) for qk in q[ident]]
    y = np.zeros(3)
    for _ in range(200):
        nominal = np.array([r @ y + t for r, t in flanges])
        rx, tx = svd_register(nominal, p[ident])
        a = np.zeros((3 * len(flanges), 6))
        b = np.zeros(3 * len(flanges))
        for i, (r, t) in enumerate(flanges):
            a[3 * i:3 * i + 3, :3] = rx @ r
            a[3 * i:3 * i + 3, 3:] = np.eye(3)
            b[3 * i:3 * i + 3] = p[ident][i] - rx @ t
        y = np.linalg.lstsq(a, b, rcond=None)[0][:3]
    nominal = np.array([r @ y + t for r, t in flanges])
    rx, tx = svd_register(nominal, p[ident])
    pb = (rx.T @ (p - tx).T).T  # the measurements in the robot base frame (mm)

    def write_csv(path, sel):
        with open(path, "w") as f:
            f.write(",".join(["x1", "y1", "z1"] + names) + "\n")
            for k in np.nonzero(sel)[0]:
                f.write(",".join(f"{v:.12g}" for v in list(pb[k] / 1000.0) + list(q[k])) + "\n")

    write_csv(os.path.join(work, "fig_ident.csv"), ident)
    write_csv(os.path.join(work, "fig_valid.csv"), valid)
    config = {
        "robot": {"name": "irb120"},
        "tasks": {
            "calibration": {
                "enabled": True,
                "type": "kinematic_calibration",
                "kinematics": {"base_frame": "universe", "tool_frame": "flange"},
                "measurements": {
                    "markers": [{"ref_joint": "q6", "measurable_dof": [True, True, True, False, False, False]}],
                    "poses": {"base_pose": [0, 0, 0, 0, 0, 0], "tool_pose": [float(v) / 1000 for v in y] + [0.0, 0.0, 0.0]},
                },
                "parameters": {"calibration_level": "full_params", "include_non_geometric": False},
                "data": {"source_file": os.path.join(work, "fig_ident.csv"),
                         "validation_data_file": os.path.join(work, "fig_valid.csv"),
                         "number_of_samples": int(ident.sum())},
            }
        },
    }
    cfg = os.path.join(work, "figaroh.yaml")
    with open(cfg, "w") as f:
        yaml.safe_dump(config, f)

    class Irb120Calibration(BaseCalibration):
        pass

    t = time.perf_counter()
    c = Irb120Calibration(robot, cfg)
    # Neither frame is known: FIGAROH identifies the base placement and the tool offset too
    # (as kinecal does); this release reads these keys without setting them from the file.
    c.calib_config.setdefault("known_baseframe", False)
    c.calib_config.setdefault("known_tipframe", False)
    c.initialize()
    c.solve()
    fwall = time.perf_counter() - t
    metrics = c._compute_validation_metrics() or {}
    print("FIGAROH", getattr(sys.modules.get("figaroh"), "__version__", "?"), "on the IRB 120, reflector 1, idx < 500 / >= 500")
    print(f"  time {fwall:.2f} s (in-process, initialize + solve); status {c.STATUS}")
    for k, v in metrics.items():
        print(f"  {k}: {str(v)[:300]}")
    # The errors as kinecal prints them, from FIGAROH's held-out residuals (m -> mm).
    res = np.asarray(metrics.get("residuals_calibrated", []), dtype=float).reshape(3, -1).T * 1000.0  # stacked by axis
    if len(res):
        e = np.linalg.norm(res, axis=1)
        print(f"FIGAROH held-out: mean {e.mean():.4f} / RMS {np.sqrt((e ** 2).mean()):.4f} / max {e.max():.4f} mm ({len(e)} poses)")
    v = rep["validation"]["after_stats"]
    print(f"kinecal identify (whole process, frames estimated from the raw tracker data): {kwall * 1000:.0f} ms; "
          f"held-out mean {v['position_mean_mm']:.4f} / RMS {v['position_rms_mm']:.4f} / max {v['position_max_mm']:.4f} mm")


if __name__ == "__main__":
    main()
