"""The CHNS wire format, pinned by the transcripts of docs/instruments/reference.md.

The first transcript is replayed on the simulator (byte-identical replies); the second is served by a
scripted device on a real pty to the real driver, which must send exactly its bytes and turn its
stream lines into samples (session time, mm, NaN for a missing coordinate).
"""

from __future__ import annotations

import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.core.clock import SessionClock
from mirrorlab.core.devices import SimulatorServer
from mirrorlab.core.errors import ConfigurationError, DeviceReplyError
from mirrorlab.core.streams import Emitter, StreamRouter
from mirrorlab.instruments.reference import ChainSource
from mirrorlab.instruments.reference.chains import (
    ARM_AXES,
    ARM_JOINTS,
    ARM_LENGTHS,
    arm_angles,
    arm_positions,
    generated_arm,
    simulated_chain,
)
from mirrorlab.instruments.reference.models import ChainSourceModel
from mirrorlab.plugins.kinematics.io import write_c3d
from mirrorlab.plugins.retarget import Chain

from tests.instruments.transcripts import replay_on_model, scripted_driver, transcripts
from tests.tolerances import roundoff

SIMULATOR, DRIVER = [t for t in transcripts("reference.md") if any("CHNS" in line for line in t)]
FRAMES = np.array([[[0, 0, 0], [300, 0, 0], [300, 250.5, 0]], [[0, 0, 0], [0, 300, 0], [np.nan] * 3]])


def test_simulator_answers_the_documented_transcript() -> None:
    replay_on_model(ChainSourceModel(FRAMES, ["shoulder", "elbow", "hand"], 100.0), SIMULATOR)


def test_driver_sends_the_documented_bytes_and_parses_the_stream() -> None:
    router, clock = StreamRouter(), SessionClock()
    stop = threading.Event()
    with scripted_driver(DRIVER, ChainSource, "mocap", {"rate": 120.0, "joints": "RightArm,RightHand"}) as source:
        emit = Emitter("mocap", router, clock, {s.name: s for s in source.streams()})
        with router.subscribe([("mocap", "joints"), ("mocap", "frame")]) as live:
            thread = threading.Thread(target=source.acquire, args=(emit, stop))
            thread.start()
            blocks = [live.get(timeout=10) for _ in range(4)]
            stop.set()
            thread.join(10)
    joints = [b for b in blocks if b.stream == "joints"]
    frames = [int(b.values[0]) for b in blocks if b.stream == "frame"]
    assert frames == [7, 8]
    np.testing.assert_array_equal(joints[0].values[0], [[0, 0, 0], [300, -250.5, 0.012]])
    np.testing.assert_array_equal(joints[1].values[0], [[1, np.nan, np.nan], [np.nan] * 3])
    # The script sends both lines at once: DeviceClock keeps each sample no later than its arrival,
    # so the second is stamped at most the device's 8.333 ms after the first.
    # (the difference of two session stamps, each rounded at its magnitude)
    assert 0 < joints[1].times[0] - joints[0].times[0] <= 0.008333 + roundoff(scale=abs(joints[1].times[0]), ops=2)
    stamps = [[s.device_s for s in source.parse_stream_line(line[3:])] for line in DRIVER[-2:]]
    assert stamps == [[1.5, 1.5], [1.508333, 1.508333]]  # joints and frame of each line, device seconds


@pytest.mark.parametrize("fields", [["7", "1", "2"], ["x", "0", "0", "0", "0", "0", "0"], ["7", "a", "0", "0", "0", "0", "0"]])
def test_malformed_stream_lines_are_refused(fields: list[str]) -> None:
    source = ChainSource("mocap", port="loop://", settings={"joints": "a,b"})
    with pytest.raises(ValueError):
        source.parse_fields(fields)


def test_unknown_joint_is_a_device_error_naming_the_joints() -> None:
    with SimulatorServer(ChainSource.make_simulator({}, 0)) as server:
        source = ChainSource("mocap", port=server.url, settings={"joints": "shoulder,knee"})
        source.connect()
        try:
            with pytest.raises(DeviceReplyError, match="no joint knee; joints: shoulder elbow wrist hand"):
                source.configure()
        finally:
            source.close()


def test_generated_arm_keeps_its_link_lengths() -> None:
    X = generated_arm()
    lengths = np.linalg.norm(np.diff(X, axis=1), axis=-1)
    # forward kinematics (a few rotations) of coordinates up to |X|: ~20 roundings
    np.testing.assert_allclose(lengths, np.broadcast_to([300.0, 250.0, 80.0], lengths.shape), rtol=0,
                               atol=roundoff(scale=np.abs(X).max(), ops=20))
    assert X.shape == (1000, len(ARM_JOINTS), 3) and np.ptp(X[:, 3], axis=0).min() > 50  # it moves in 3-D


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-3.2, 3.2), min_size=4, max_size=4))
def test_arm_forward_kinematics_is_the_retarget_chain(q: list[float]) -> None:
    """The instrument's own forward kinematics of its arm against the retarget plugin's chain."""
    chain = Chain(list(ARM_LENGTHS), list(ARM_AXES))
    angles = np.concatenate([[q], arm_angles(50)])
    expected = chain.forward(angles)
    # three rotations and a running sum of links up to |X| ~ 630 mm: ~20 roundings
    assert np.abs(arm_positions(angles) - expected).max() <= roundoff(scale=np.abs(expected).max(), ops=20)


def test_a_recorded_motion_is_read_by_the_plugin_answering_the_hook(tmp_path: Path) -> None:
    """A marker file played by the simulator: read through ``mirrorlab_read_motion`` (the retarget
    plugin's readers), with ``A+B`` a midpoint, ``scale`` and ``skip`` applied."""
    rng = np.random.default_rng(3)
    points = rng.uniform(-500.0, 500.0, (12, 3, 3))
    path = tmp_path / "arm.c3d"
    write_c3d(path, ["SHO", "ELB1", "ELB2"], 50.0, points)
    positions, names, rate = simulated_chain(str(path), ["SHO", "ELB1+ELB2"], scale=2.0, skip=2)
    assert names == ["SHO", "ELB1+ELB2"] and rate == 50.0 and positions.shape == (10, 2, 3)
    expected = 2.0 * np.stack([points[2:, 0], points[2:, 1:].mean(axis=1)], axis=1)
    # the C3D stores float32 coordinates: half an ulp (2^-24 relative) of each, a midpoint of two at
    # most one ulp (2^-23) of the scaled coordinates
    assert np.abs(positions - expected).max() <= 2.0 ** -23 * np.abs(expected).max()


def test_an_unreadable_recording_is_a_configuration_error_naming_the_file(tmp_path: Path) -> None:
    with pytest.raises(ConfigurationError, match=r"chain source simulator: .*nothing\.bvh"):
        ChainSource.make_simulator({"motion": str(tmp_path / "nothing.bvh")}, seed=0)
    path = tmp_path / "arm.c3d"
    write_c3d(path, ["SHO", "ELB"], 50.0, np.zeros((3, 2, 3)))
    with pytest.raises(ConfigurationError, match="chain source simulator: .*WRI"):
        ChainSource.make_simulator({"motion": str(path), "joints": "SHO,WRI"}, seed=0)


def test_reading_a_recording_imports_only_the_plugin_that_declares_the_hook(tmp_path: Path) -> None:
    """``mirrorlab_read_motion`` is declared in ``mirrorlab.provides``: a fresh process imports the
    retarget plugin (and what it uses) for it, and no other plugin."""
    path = tmp_path / "arm.c3d"
    write_c3d(path, ["SHO", "ELB"], 50.0, np.ones((3, 2, 3)))
    probe = ("import sys\nfrom mirrorlab.instruments.reference.chains import simulated_chain\n"
             f"print(simulated_chain({str(path)!r}, ['SHO', 'ELB'])[0].shape)\n"
             "print(sorted({'.'.join(m.split('.')[:3]) for m in sys.modules if m.startswith('mirrorlab.plugins.')}))")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True).stdout.splitlines()
    assert out[0] == "(3, 2, 3)"
    assert out[1] == "['mirrorlab.plugins.kinematics', 'mirrorlab.plugins.retarget']"
