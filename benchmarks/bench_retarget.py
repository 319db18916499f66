"""Batch retargeting speed, 6 -> 4 DOF (spec T2 chains, T3 motion), against a per-frame scipy baseline.

    python benchmarks/bench_retarget.py [--frames 3000]

Baseline (measured in the same run): a plain per-frame loop of scipy.optimize.least_squares
(method "lm", analytic Jacobian, warm-started from the previous frame). Goal: >= 2000 frames/s
for the blocked batch (issue 13).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from mirrorlab.plugins.retarget import Chain, Objective, approximate, correspondence_pairs
from mirrorlab.plugins.retarget.correspondence import serial_parents
from scipy.optimize import least_squares


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=3000)
    T = ap.parse_args().frames
    inp = Chain([1.0] * 6, ["z", "y"] * 3)
    out = Chain([1.5] * 4, ["z", "y", "z", "y"])
    X = inp.forward(0.6 * np.sin(0.05 * np.arange(T)[:, None] + np.arange(6)))
    obj = Objective(out, correspondence_pairs(serial_parents(7), inp.lengths, out), serial_parents(7))
    R, p = np.eye(3), np.zeros(3)

    t0 = time.perf_counter()
    q, f_base = np.zeros(4), np.empty(T)
    for k in range(T):
        arms = obj.arms(X[k:k + 1])
        sol = least_squares(lambda x, a=arms: obj.residuals(x[None], a, R, p)[0].ravel(), q,
                            jac=lambda x, a=arms: obj.residuals_jacobian(x[None], a, R, p)[1].reshape(-1, 4),
                            method="lm")
        q, f_base[k] = sol.x, 2 * sol.cost
    base = T / (time.perf_counter() - t0)
    rows = [("scipy least_squares per frame (baseline)", base, f_base)]
    for label, block in (("approximate, sequential (block=0)", 0), ("approximate, blocked (block=32)", 32)):
        t0 = time.perf_counter()
        res = approximate(X, out, block=block)
        rows.append((label, T / (time.perf_counter() - t0), res.f))
    print(f"6 -> 4 DOF, {T} frames (T2 chains, T3 motion)")
    print(f"{'method':40s} {'frames/s':>10s} {'x baseline':>11s} {'mean f':>10s}")
    for label, fps, f in rows:
        print(f"{label:40s} {fps:10.0f} {fps / base:11.2f} {np.mean(f):10.6f}")


if __name__ == "__main__":
    main()
