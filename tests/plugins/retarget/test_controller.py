"""The ``retarget`` controller on live streams from simulated serial instruments over real ptys.

Every wait is on data (a subscription's samples), never on the clock. The checks are against the
batch (:func:`approximate` of the very input frames the session recorded), the 50-start multistart
optimum and an analytic case (a one-link virtual input chain copied by a one-link output chain).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core import Session, ValidationError
from mirrorlab.plugins.retarget import Chain, Objective, approximate
from mirrorlab.plugins.retarget.solvers import multistart, start_points

from tests.plugins.retarget.optimum import LM_XTOL, optimum_bounds
from tests.tolerances import roundoff

from .test_stream import ARM, BVH, CMU_MM

ARM4 = {"lengths": "295.87,229.54", "axes": "zyx,y", "rate": "120 Hz"}


def record_until(s: Session, source: str, stream: str, samples: int) -> None:
    """Record from the first sample until ``source/stream`` has published ``samples`` samples."""
    with s.subscribe(source, stream, max_bytes=1 << 24) as live:
        s.start_recording()                       # before acquiring: every input sample is in the file
        s.start_acquisition()
        seen = 0
        while seen < samples:
            block = live.get(timeout=30)
            assert block is not None, f"{source}/{stream} stopped publishing"
            seen += len(block.times)
        s.stop_acquisition()                      # the controller stops first, then the instruments and the file


@pytest.mark.data
@pytest.mark.parametrize("wait", [True, False])
def test_live_bvh_arm_is_the_batch_result_at_the_optimum_without_flips(tmp_path: Path, wait: bool) -> None:
    with Session.create(tmp_path / "live.h5") as s:
        s.add_instrument("mocap", "chain_source", simulate=True,
                         settings={"motion": str(BVH), "joints": ",".join(ARM), "scale": CMU_MM, "skip": 1,
                                   "rate": "120 Hz"})
        s.add_instrument("elbow", "actuator", simulate=True, settings={"speed": "20 rad/s"})
        s.add_controller("arm4", "retarget", settings={**ARM4, "actuate": "3", "wait": wait},
                         inputs={"input": "mocap/joints"}, instruments={"q3": "elbow"})
        record_until(s, "arm4", "q", 240)
        t_in, X = s.stream("mocap", "joints")
        _, frames = s.stream("mocap", "frame")
        t_out, q = s.stream("arm4", "q")
        _, f = s.stream("arm4", "f")
        _, joints = s.stream("arm4", "joints")
        _, latency = s.stream("arm4", "compute_latency")
        _, missed = s.stream("arm4", "missed")
        _, target = s.stream("arm4", "q3.target")
    assert len(t_out) >= 240 and np.all(np.diff(frames) == 1)          # consecutive frames of the file, none lost
    # the controller subscribes once its instrument streams, so it may miss the first samples, and stops
    # before it, so it may leave the last ones; in between one output per input sample, stamped with its time
    k0 = int(np.searchsorted(t_in, t_out[0]))
    assert np.array_equal(t_out, t_in[k0:k0 + len(t_out)])
    X = X[k0:k0 + len(t_out)]
    robot = Chain([295.87, 229.54], ["zyx", "y"])
    batch = approximate(X, robot, block=0)
    assert np.array_equal(q, batch.q) and np.array_equal(f, batch.f)   # deterministic: the batch exactly
    # the same angles through the forward kinematics, one row vs all rows: rounding of |joints|
    np.testing.assert_allclose(joints, batch.joints, rtol=0, atol=roundoff(scale=np.abs(batch.joints).max(), ops=20))
    obj = Objective(robot, batch.pairs, batch.input.parents)
    arms = obj.arms(X)
    ms = multistart(obj, start_points(obj, 50, seed=7), arms, np.eye(3), X[:, 0])
    # f at the multistart optimum: both within their solvers' bounds of the same minimum
    close = optimum_bounds(obj, q, arms, np.eye(3), X[:, 0]).f + optimum_bounds(obj, ms.q, arms, np.eye(3), X[:, 0]).f
    assert np.mean(f <= ms.f + close) >= 0.99
    assert np.abs(np.diff(q, axis=0)).max() < 0.5                   # no branch flips
    assert np.all(latency >= 0)
    assert np.array_equal(missed, np.cumsum(latency > 1 / 120.0))   # the counter counts late outputs
    wrapped = np.array([math.remainder(v, 2 * math.pi) for v in q[:, 3]])
    sent = roundoff(scale=np.pi, ops=2)                 # the actuator's target: the angle as sent, to rounding
    if wait:  # every frame's elbow angle, acknowledged before the next frame
        np.testing.assert_allclose(target, wrapped, rtol=0, atol=sent)
    else:  # from the sender thread: frames' angles in order, one replaced by a newer one left out
        k = [int(np.argmin(np.abs(wrapped - v))) for v in target]
        np.testing.assert_allclose(wrapped[k], target, rtol=0, atol=sent)
        assert k == sorted(set(k)) and len(k) >= 0.5 * len(q)


def test_virtual_input_chain_angles_from_a_live_angle_stream(tmp_path: Path) -> None:
    """A one-link virtual input chain (its angle from a live ``angle_source``) on a one-link output
    chain of the same length: q is the input angle and f is 0."""
    with Session.create(tmp_path / "virtual.h5") as s:
        s.add_instrument("sensor", "angle_source", simulate=True,
                         settings={"rate": "100 Hz", "amplitude": "40 deg", "frequency": "1 Hz"})
        s.add_controller("copy", "retarget", settings={"lengths": "300", "axes": "z", "input_lengths": "300",
                                                       "input_axes": "z"},
                         inputs={"input": "sensor/angle"})
        record_until(s, "copy", "q", 100)
        t_in, angle = s.stream("sensor", "angle")
        t_out, q = s.stream("copy", "q")
        _, f = s.stream("copy", "f")
    k0 = int(np.searchsorted(t_in, t_out[0]))
    assert np.array_equal(t_out, t_in[k0:k0 + len(q)]) and len(q) >= 100 and np.ptp(angle) > 0.5
    # f* = 0 at the input angle: LM stops within its xtol of it (or at the rounding of the 300 mm
    # link's coordinates, relative to the link); f is then at most the squared distance of the tip
    tol_q = LM_XTOL + roundoff(scale=300.0, ops=10) / 300.0
    np.testing.assert_allclose(q[:, 0], angle[k0:k0 + len(q)], rtol=0, atol=tol_q)
    assert np.abs(f).max() <= 2 * (300.0 * tol_q) ** 2



@pytest.mark.parametrize(("settings", "key", "reason"), [
    ({**ARM4, "actuate": "4"}, "actuate", "indices must lie in 0..3"),
    ({**ARM4, "actuate": "elbow"}, "actuate", "not a list of angle indices"),
    ({**ARM4, "input_lengths": "300,200", "input_axes": "z"}, "input_axes", "one per joint"),
])
def test_bad_settings_name_the_key(tmp_path: Path, settings: dict, key: str, reason: str) -> None:
    with Session.create(tmp_path / "bad.h5") as s, pytest.raises(ValidationError, match=reason) as err:
        s.add_controller("arm4", "retarget", settings=settings, inputs={"input": "mocap/joints"})
    assert err.value.problems[0].key == f"controllers.arm4.settings.{key}"


def test_live_recipe_warns_with_the_count_of_frames_it_could_not_compute(tmp_path: Path) -> None:
    """A filter that cannot keep up with its input (a 30-angle arm at 1000 input frames/s: about 100
    times the compute rate of this machine) leaves frames without output; the run says how many,
    once, at the end (it said nothing). At a rate it keeps up with, the run is quiet."""
    import re

    from tests.support import REPO, run_cli

    recipe = str(REPO / "sessions" / "retarget_live.toml")
    no_actuator = ["--set", 'controllers.arm4.settings.actuate=""', "--set", "controllers.arm4.instruments={}"]
    arm30 = ["--set", f'controllers.arm4.settings.lengths="{",".join(["52.5"] * 10)}"',
             "--set", f'controllers.arm4.settings.axes="{",".join(["zyx"] * 10)}"']
    out = tmp_path / "behind.h5"
    proc = run_cli("run", recipe, "--out", str(out), "--no-progress", "--set", 'instruments.mocap.settings.rate="1000 Hz"',
                   "--set", "steps.0.seconds=0.5", *no_actuator, *arm30)
    assert proc.returncode == 0, proc.stderr
    warnings = re.findall(r"controller 'arm4' fell behind its input: (\d+) input samples got no output", proc.stderr)
    assert len(warnings) == 1, proc.stderr
    with Session.open(out) as s:
        inputs, outputs = len(s.stream("mocap", "joints").times), len(s.stream("arm4", "q").times)
    assert 0 < int(warnings[0]) <= inputs - outputs, (warnings, inputs, outputs)
    quiet = run_cli("run", recipe, "--out", str(tmp_path / "quiet.h5"), "--no-progress",
                    "--set", 'instruments.mocap.settings.rate="20 Hz"', "--set", "steps.0.seconds=0.5", *no_actuator)
    assert quiet.returncode == 0 and "fell behind" not in quiet.stderr, quiet.stderr
