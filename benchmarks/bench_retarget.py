"""Retargeting speed: batch 6 -> 4 DOF, and the streaming filter on the CMU right arm at 120 Hz.

    python benchmarks/bench_retarget.py [--frames 3000] [--only batch|stream]

Batch (spec T2 chains, T3 motion); baseline measured in the same run: a plain per-frame loop of
scipy.optimize.least_squares (method "lm", analytic Jacobian, warm-started from the previous frame).
Goal: >= 2000 frames/s for the blocked batch (issue 13).

Stream: ../shared/data/bvh/01_01.bvh right arm (2751 frames, 120 Hz) on a 4-DOF arm (zyx shoulder,
y elbow) through RetargetFilter in deterministic mode (every frame computed once, in order);
per-frame compute time (wall clock, as the filter's latency counter, and CPU time) and frames over
the 8.3 ms deadline. Baseline measured in the same run: the same filter with a compute module that
calls scipy least_squares per frame, warm-started (no multistart). Goal: p99 well under 8.3 ms.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from mirrorlab.plugins.retarget import Chain, Objective, approximate, correspondence_pairs, input_chain
from mirrorlab.plugins.retarget.correspondence import serial_parents
from mirrorlab.plugins.retarget.sources import read_bvh_chain
from mirrorlab.plugins.retarget.stream import Compute, MemorySink, RetargetFilter, compute_for, poses
from scipy.optimize import least_squares

BVH = Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / "bvh" / "01_01.bvh"


def scipy_frame(obj: Objective, q: np.ndarray, X: np.ndarray, R: np.ndarray, p: np.ndarray) -> tuple[np.ndarray, float]:
    """One frame by scipy's MINPACK LM, warm-started at q: angles (dof,) rad and f mm²."""
    arms = obj.arms(X[None])
    m = q.size
    sol = least_squares(lambda x: obj.residuals(x[None], arms, R, p)[0].ravel(), q,
                        jac=lambda x: obj.residuals_jacobian(x[None], arms, R, p)[1].reshape(-1, m), method="lm")
    return sol.x, 2 * sol.cost


def batch(T: int) -> None:
    inp = Chain([1.0] * 6, ["z", "y"] * 3)
    out = Chain([1.5] * 4, ["z", "y", "z", "y"])
    X = inp.forward(0.6 * np.sin(0.05 * np.arange(T)[:, None] + np.arange(6)))
    obj = Objective(out, correspondence_pairs(serial_parents(7), inp.lengths, out), serial_parents(7))
    R, p = np.eye(3), np.zeros(3)

    t0 = time.perf_counter()
    q, f_base = np.zeros(4), np.empty(T)
    for k in range(T):
        q, f_base[k] = scipy_frame(obj, q, X[k], R, p[None])
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


class ScipyCompute:
    """Baseline compute module: scipy least_squares per frame, warm-started, output base on the input root."""

    def __init__(self, compute: Compute) -> None:
        self.objective, self.flag_above = compute.objective, np.inf
        self.q = compute.q0.copy()

    def __call__(self, X: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, int, bool]:
        self.q, f = scipy_frame(self.objective, self.q, X, np.eye(3), X[:1])
        return self.q, f, np.zeros(0), 0, False


def stream() -> None:
    m = read_bvh_chain(BVH, ["RightArm", "RightForeArm", "RightHand", "RFingers"], scale=25.4 / 0.45, skip=1)
    L = input_chain(m.joints).lengths
    robot = Chain([L[0], L[1] + L[2]], ["zyx", "y"])
    period = 1.0 / m.rate
    rows = []
    for label, compute in (("scipy least_squares per frame (baseline)", ScipyCompute(compute_for(m.joints, robot))),
                           ("RetargetFilter lm (warm start + multistart)", compute_for(m.joints, robot))):
        sink = MemorySink()
        c0 = time.process_time()
        stats = RetargetFilter(compute, m.rate, [sink]).run(poses(m.joints, m.time))
        cpu = (time.process_time() - c0) / stats.computed
        lat = np.array(stats.latencies)
        rows.append((label, lat.mean(), np.percentile(lat, 99), lat.max(), cpu, stats.missed_deadlines,
                     int(sink.arrays()["restarted"].sum()), np.mean(sink.arrays()["f"])))
    print(f"\nCMU 01_01 right arm -> 4-DOF arm, {len(m.joints)} frames streamed at {m.rate:g} Hz "
          f"(deterministic mode, deadline {1e3 * period:.1f} ms)")
    print(f"{'compute module':44s} {'mean ms':>8s} {'p99 ms':>8s} {'max ms':>8s} {'cpu ms':>7s} {'missed':>7s} "
          f"{'restarts':>8s} {'x baseline':>11s} {'mean f':>8s}")
    base = rows[0][1]
    for label, mean, p99, mx, cpu, missed, restarts, f in rows:
        print(f"{label:44s} {1e3 * mean:8.3f} {1e3 * p99:8.3f} {1e3 * mx:8.2f} {1e3 * cpu:7.3f} {missed:7d} "
              f"{restarts:8d} {base / mean:11.2f} {f:8.3f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--frames", type=int, default=3000, help="frames of the batch benchmark")
    ap.add_argument("--only", choices=("batch", "stream"), help="run one of the two benchmarks")
    args = ap.parse_args()
    if args.only != "stream":
        batch(args.frames)
    if args.only != "batch":
        stream()


if __name__ == "__main__":
    main()
