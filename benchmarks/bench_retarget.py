"""Retargeting speed: batch 6 -> 4 DOF, and the streaming filter on the CMU right arm at 120 Hz.

    python benchmarks/bench_retarget.py [--frames 3000] [--only batch|stream]

Batch (spec T2 chains, T3 motion); baseline measured in the same run: a plain per-frame loop of
scipy.optimize.least_squares (method "lm", analytic Jacobian, warm-started from the previous frame).
Goal: >= 2000 frames/s for the blocked batch (issue 13).

Stream: ../shared/data/bvh/01_01.bvh right arm (2751 frames, 120 Hz) on a 4-DOF arm (zyx shoulder,
y elbow) through RetargetFilter, in deterministic mode (every frame computed once, in order, back to
back: latency = compute time) and in real-time mode (input, compute and output threads at 120 Hz,
about 23 s each: latency = input arrival to result), with the multistart fallback on the frame that
needs it, in a worker thread and in a worker process (the filter's default for real time). Columns:
latency mean/p99/max, CPU per computed frame, the largest latency of a frame that ran, started or
adopted a multistart (ms@ms), output ticks that missed the 8.3 ms deadline, inputs overwritten
before being computed, multistarts, background results adopted late, published frames whose f is at
the 50-start optimum (goal >= 99 %), angle steps > 0.5 rad between published frames (in real time a
dropped input makes a longer step), and published frames whose angles differ from the deterministic
batch result of the same input frame by more than 1e-3 rad (off; a branch flip would count).
Baseline measured in the same run: the same filter with a compute
module that calls scipy least_squares per frame, warm-started (no multistart). Goal: no missed
deadline in real time. A second table isolates the GIL: frames computed back to back while the
worker (thread or process) runs one multistart after another, against no multistart at all.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
from mirrorlab.plugins.retarget import Chain, Objective, Tracker, approximate, correspondence_pairs, input_chain
from mirrorlab.plugins.retarget.correspondence import serial_parents
from mirrorlab.plugins.retarget.solvers import Solution, multistart, start_points
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

    def open(self) -> None:
        pass

    def close(self) -> None:
        pass

    def __call__(self, X: np.ndarray) -> tuple[np.ndarray, float, np.ndarray, int, bool, bool]:
        self.q, f = scipy_frame(self.objective, self.q, X, np.eye(3), X[:1])
        return self.q, f, np.zeros(0), 0, False, False


class ThreadWorker:
    """The background multistart in a thread of this process (the alternative to FallbackWorker's process)."""

    def __init__(self, tracker: Tracker) -> None:
        self.tracker, self.pool, self.job, self.busy = tracker, ThreadPoolExecutor(1), None, False

    def submit(self, arms, R_b, p_b, warm) -> None:  # noqa: ANN001 - FallbackWorker's signature
        self.job, self.busy = self.pool.submit(self.tracker.fallback, arms, R_b, p_b, warm), True

    def ready(self) -> bool:
        return self.busy and self.job.done()

    def result(self) -> Solution:
        self.busy = False
        return self.job.result()

    def close(self) -> None:
        self.pool.shutdown()


def stream() -> None:
    m = read_bvh_chain(BVH, ["RightArm", "RightForeArm", "RightHand", "RFingers"], scale=25.4 / 0.45, skip=1)
    L = input_chain(m.joints).lengths
    robot = Chain([L[0], L[1] + L[2]], ["zyx", "y"])
    period = 1.0 / m.rate
    obj = compute_for(m.joints, robot).objective
    starts = start_points(obj, 50, seed=7)
    X = m.joints
    best = np.concatenate([multistart(obj, starts, obj.arms(X[i:i + 250]), np.eye(3), X[i:i + 250, 0]).f
                           for i in range(0, len(X), 250)])           # the 50-start optimum per frame (mm²)
    q_batch = approximate(X, robot).q                                     # the sequential result per frame (rad)
    cases = (("scipy least_squares per frame (baseline)", False, ScipyCompute(compute_for(X, robot))),
             ("lm, multistart on the frame", False, compute_for(X, robot)),
             ("lm, multistart in a worker process", False, compute_for(X, robot, fallback_delay=None)),
             ("lm, multistart on the frame", True, compute_for(X, robot)),
             ("lm, multistart in a worker thread", True, compute_for(X, robot, fallback_delay=None,
                                                                      worker=ThreadWorker)),
             ("lm, multistart in a worker process", True, compute_for(X, robot, fallback_delay=None)))
    print(f"\nCMU 01_01 right arm -> 4-DOF arm, {len(X)} frames at {m.rate:g} Hz (deadline {1e3 * period:.1f} ms); "
          "deterministic: every frame computed once, back to back; real time: input, compute and output threads")
    print(f"{'compute module':38s} {'mode':>9s} {'mean ms':>8s} {'p99 ms':>7s} {'max ms':>7s} {'cpu ms':>7s} "
          f"{'ms@ms':>6s} {'missed':>6s} {'dropped':>7s} {'restarts':>8s} {'adopted':>7s} {'optimum':>8s} {'jumps':>5s} "
          f"{'off':>4s} {'x baseline':>10s}")
    base = None
    for label, realtime, compute in cases:
        sink = MemorySink()
        c0 = time.process_time()
        stats = RetargetFilter(compute, m.rate, [sink]).run(poses(X, m.time), realtime=realtime)
        cpu = (time.process_time() - c0) / stats.computed
        lat = np.array(stats.latencies)
        out = sink.arrays()
        base = base or lat.mean()
        at_optimum = np.mean(out["f"] <= best[out["index"]] * (1 + 1e-6) + 1e-9)
        jumps = int(np.sum(np.abs(np.diff(out["q"], axis=0)).max(axis=1) > 0.5))
        at_ms = out["latency"][out["restarted"] | out["adopted"]]     # frames that start or adopt a multistart
        off = int(np.sum(np.abs(out["q"] - q_batch[out["index"]]).max(axis=1) > 1e-3))
        print(f"{label:38s} {'real time' if realtime else 'determ.':>9s} {1e3 * lat.mean():8.3f} "
              f"{1e3 * np.percentile(lat, 99):7.3f} {1e3 * lat.max():7.2f} {1e3 * cpu:7.3f} "
              f"{1e3 * at_ms.max() if at_ms.size else np.nan:6.1f} {stats.missed_deadlines:6d} "
              f"{stats.dropped:7d} {stats.restarts:8d} {stats.late_adoptions:7d} {100 * at_optimum:7.2f}% {jumps:5d} {off:4d} "
              f"{base / lat.mean():10.2f}")
    print("ms@ms: largest latency of a published frame that ran, started or adopted a multistart; off: published\n"
          "frames whose angles differ from the deterministic (batch) result of the same frame by > 1e-3 rad")

    # The GIL, isolated: the worker kept busy (a multistart whenever it is free: jump factor 0), frames
    # computed back to back; the compute time of a frame while a thread or a process runs a multistart.
    print("\nthe same, deterministic, with a multistart started whenever the worker is free (jump factor 0)")
    print(f"{'worker':38s} {'mean ms':>8s} {'p99 ms':>7s} {'max ms':>7s} {'restarts':>8s} {'x none':>7s}")
    none = None
    for label, compute in (("none (no multistart)", compute_for(X, robot, multistart=False)),
                           ("thread", compute_for(X, robot, fallback_delay=None, jump_factor=0.0, worker=ThreadWorker)),
                           ("process", compute_for(X, robot, fallback_delay=None, jump_factor=0.0))):
        stats = RetargetFilter(compute, m.rate).run(poses(X, m.time))
        lat = np.array(stats.latencies)
        none = none or lat.mean()
        print(f"{label:38s} {1e3 * lat.mean():8.3f} {1e3 * np.percentile(lat, 99):7.3f} {1e3 * lat.max():7.2f} "
              f"{stats.restarts:8d} {lat.mean() / none:7.2f}")


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
