"""Side-by-side: pybotics (MDH + scipy least_squares) on the IRB 120 tracker data, position-only
calibration from reflector 1, identify on idx < 500, validate on idx >= 500 — the same split and
measurement as `kinecal irb120` (row "reflector 1: full geometric").

    pip install pybotics
    python3 benches/peers/pybotics_irb120.py ../shared/data/irb120

pybotics needs a starting world frame: it gets the same SVD registration kinecal starts from
(alternating SVD and linear least squares for the flange offset), computed here with numpy.
"""
import sys
import time

import numpy as np
from scipy.optimize import least_squares
from pybotics.optimization import OptimizationHandler, optimize_accuracy, compute_absolute_errors
from pybotics.predefined_models import abb_irb120
from pybotics.robot import Robot
from pybotics.tool import Tool


def load(folder):
    joints = np.loadtxt(f"{folder}/joints_deg.csv", delimiter=",", skiprows=1)
    smr1 = np.loadtxt(f"{folder}/smr1.csv", delimiter=",", skiprows=1)
    return joints[:, 0], np.deg2rad(joints[:, 1:]), smr1[:, 1:]


def svd_register(src, dst):
    cs, cd = src.mean(0), dst.mean(0)
    z = (dst - cd).T @ (src - cs)
    u, _, vt = np.linalg.svd(z)
    d = np.eye(3)
    d[2, 2] = np.sign(np.linalg.det(u @ vt))
    r = u @ d @ vt
    return r, cd - r @ cs


def register(robot, qs, pts):
    flanges = [robot.fk(q) for q in qs]
    y = np.zeros(3)
    for _ in range(200):
        nominal = np.array([f[:3, :3] @ y + f[:3, 3] for f in flanges])
        r, p = svd_register(nominal, pts)
        a = np.zeros((3 * len(qs), 6))
        b = np.zeros(3 * len(qs))
        for i, f in enumerate(flanges):
            a[3 * i:3 * i + 3, :3] = r @ f[:3, :3]
            a[3 * i:3 * i + 3, 3:] = np.eye(3)
            b[3 * i:3 * i + 3] = pts[i] - r @ f[:3, 3]
        sol = np.linalg.lstsq(a, b, rcond=None)[0]
        if np.linalg.norm(sol[:3] - y) < 1e-9:
            y = sol[:3]
            break
        y = sol[:3]
    nominal = np.array([f[:3, :3] @ y + f[:3, 3] for f in flanges])
    r, p = svd_register(nominal, pts)
    world = np.eye(4)
    world[:3, :3], world[:3, 3] = r, p
    return world, y


def stats(e):
    return f"mean {e.mean():.3f}  RMS {np.sqrt((e ** 2).mean()):.3f}  max {e.max():.3f} mm"


def main(folder):
    idx, qs, pts = load(folder)
    train, test = idx < 500, idx >= 500
    robot = Robot.from_parameters(abb_irb120())
    world, y = register(robot, qs[train], pts[train])
    robot.world_frame = world
    tool = Tool()
    tool.position = y
    robot.tool = tool
    print(f"pybotics, reflector 1, held-out before calibration (registered frames): {stats(compute_absolute_errors(qs[test], pts[test], robot))}")
    handler = OptimizationHandler(robot=robot, kinematic_chain_mask=True, tool_mask=[True, True, True, False, False, False], world_mask=True)
    x0 = handler.generate_optimization_vector()
    t0 = time.perf_counter()
    result = least_squares(optimize_accuracy, x0, args=(handler, qs[train], pts[train]), method="trf")
    seconds = time.perf_counter() - t0
    handler.apply_optimization_vector(result.x)
    e_train = compute_absolute_errors(qs[train], pts[train], handler.robot)
    e_test = compute_absolute_errors(qs[test], pts[test], handler.robot)
    print(f"pybotics full MDH ({len(x0)} parameters, scipy least_squares trf, {result.nfev} evaluations): {seconds * 1e3:.0f} ms")
    print(f"  identification: {stats(e_train)}")
    print(f"  validation:     {stats(e_test)}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "../shared/data/irb120")
