"""Retargeting a long motion stops at its next frame step once a stop is requested."""

from __future__ import annotations

import threading

import numpy as np
from mirrorlab.core.algorithms import RunContext, execute
from mirrorlab.core.registry import get_registry

from .test_fixtures import T1_IN


def test_a_stop_requested_during_the_frame_loop_ends_the_run() -> None:
    t = np.linspace(0, 2 * np.pi, 400)[:, None]
    joints = T1_IN.forward(0.4 * np.hstack([np.sin(t), np.cos(t), np.sin(2 * t), np.cos(3 * t)]))
    cancel = threading.Event()
    calls: list[tuple[float, float | None]] = []

    def progress(done: float, total: float | None, message: str) -> None:
        calls.append((done, total))
        if len(calls) == 3:  # the algorithm's own start report, then two frame steps
            cancel.set()

    algorithm = get_registry().algorithm("retarget")
    params = {"lengths": "2,2", "axes": "z,y"}
    out = execute(algorithm, {"joints": joints}, params, RunContext(progress, cancel))
    assert (out.status, out.error, out.outputs) == ("cancelled", "stopped on request", {})
    assert len(calls) == 3 and calls[2][1] is not None and calls[2][1] > 3  # stopped among many frame steps
    finished = execute(algorithm, {"joints": joints}, params, RunContext())
    assert finished.status == "ok" and np.isfinite(finished.outputs["q"]).all()
