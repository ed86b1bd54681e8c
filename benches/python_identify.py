"""Time of kinecal.calibrate from Python on the problem of examples/calibrate_bench.rs (IRB 120,
500 simulated full poses, 20 µm / 0.01° noise, frames from the model, one start), to compare with
the Rust call:

    pip install .
    python3 benches/python_identify.py
    cargo run --release --example calibrate_bench
"""
import time

import kinecal

m = kinecal.Model.load("irb120")
truth, data = kinecal.simulate(m, 500, seed=1, error_mm=0.5, error_deg=0.1, noise_mm=0.02, noise_deg=0.01)
reps = 200
t = time.perf_counter()
for _ in range(reps):
    cal = kinecal.calibrate(m, data, noise_mm=0.02, noise_deg=0.01, frames="model", starts=1)
ms = (time.perf_counter() - t) * 1e3 / reps
print(f"kinecal.calibrate from Python, IRB 120, 500 poses, frames from the model, 1 start: {ms:.3f} ms per call (mean of {reps}), σ̂₀ {cal.sigma0:.6f}")
