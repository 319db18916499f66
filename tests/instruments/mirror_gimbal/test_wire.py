"""The MGIM wire format, pinned by the transcripts of docs/instruments/mirror_gimbal.md.

The first transcript is replayed on the simulator (byte-identical replies for seed 0); the second
is served by a scripted device on a real pty to the real driver, which must send exactly its bytes.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from mirrorlab.core import Session
from mirrorlab.core.errors import ProtocolError
from mirrorlab.instruments.mirror_gimbal import MirrorGimbal, MirrorGimbalModel
from mirrorlab.instruments.mirror_gimbal.driver import SETPOINT_AXIS, parse_sample

from tests.instruments.transcripts import replay_on_model, scripted_driver, transcripts
from tests.tolerances import roundoff

SIMULATOR, DRIVER = transcripts("mirror_gimbal.md")


def test_simulator_answers_the_documented_transcript() -> None:
    replay_on_model(MirrorGimbalModel(seed=0), SIMULATOR)


def test_driver_sends_the_documented_bytes() -> None:
    with scripted_driver(DRIVER, MirrorGimbal, "g") as gimbal:
        gimbal.set("h_angle", 0.05).wait()
        gimbal.hold()
        reading = gimbal.read()
    assert gimbal.identity is not None and gimbal.identity.model == "GM-2"
    np.testing.assert_allclose(reading["h"], [[256.5, 1.5, math.radians(2.865)]], rtol=roundoff(ops=2))  # parsed text
    assert np.isnan(reading["v"][0, :2]).all() and reading["v"][0, 2] == 0.0


@pytest.mark.parametrize("line", ["G 1 H 1 2", "G x H 1 2 3", "G 1 Q 1 2 3", "M 1 H 1 2 3", "G 1 H a 2 3"])
def test_malformed_stream_lines_are_protocol_errors(line: str) -> None:
    with pytest.raises(ProtocolError):
        parse_sample(line)


def test_each_set_point_turns_its_own_axis(tmp_path: Path) -> None:
    """The driver looks each set-point's axis up in its declaration (``POSITION_SETPOINTS``), which names
    exactly its live parameters; ``v_angle`` sends ``POS V`` and leaves the horizontal axis alone."""
    assert sorted(SETPOINT_AXIS) == sorted(MirrorGimbal.parameters.setpoints) == ["h_angle", "v_angle"]
    with Session.create(tmp_path / "s.h5") as s:
        gimbal = s.add_instrument("g", "mirror_gimbal", simulate=True, settings={"mode_h": "pos", "mode_v": "pos"})
        model = s.simulator("g").model
        assert gimbal.set("v_angle", 0.1).wait(60.0) == 0.1
        with s.simulator("g").lock:
            h, v = model.axes["H"], model.axes["V"]
            assert (h.mode, v.mode) == ("POS", "POS") and h.setpoint == 0.0
            assert v.setpoint == pytest.approx(0.1, abs=math.radians(1e-4))  # sent as degrees with 4 decimals
