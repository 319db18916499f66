"""The long wall algorithms stop at their next check point once a stop is requested."""

from __future__ import annotations

import threading

import pytest
from mirrorlab.core.algorithms import RunContext, execute
from mirrorlab.core.registry import get_registry

SMALL = {"positions": 10, "strips": 10}


@pytest.mark.parametrize(("name", "params"), [
    ("arc_wall_grid", SMALL),
    ("optimal_wall", {**SMALL, "final_positions": 10, "final_strips": 10, "thesis_positions": 10}),
])
def test_a_stop_requested_inside_the_loop_ends_the_run(name: str, params: dict) -> None:
    cancel = threading.Event()
    calls: list[str] = []

    def progress(done: float, total: float | None, message: str) -> None:
        calls.append(message)
        if len(calls) == 3:  # the third report comes from inside the loop (the first is the algorithm's own)
            cancel.set()

    out = execute(get_registry().algorithm(name), {}, params, RunContext(progress, cancel))
    assert (out.status, out.error, out.outputs, len(calls)) == ("cancelled", "stopped on request", {}, 3)
    assert "done" not in calls  # stopped inside the loop, before the final report


@pytest.mark.parametrize("name", ["arc_wall_grid", "optimal_wall"])
def test_without_a_stop_the_loop_reports_progress_and_finishes(name: str) -> None:
    calls: list[float] = []
    params = {**SMALL, "maxiter": 3} if name == "optimal_wall" else SMALL
    out = execute(get_registry().algorithm(name), {}, params, RunContext(lambda d, t, m: calls.append(d)))
    assert out.status == "ok" and len(calls) > 3
