"""The USDF wire format, pinned by the transcripts of docs/instruments/ultrasonic_tracker.md.

The first transcript is replayed on the simulator (byte-identical replies and stream lines for
seed 0); the second is served by a scripted device on a real pty to the real driver, which must
send exactly its bytes.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mirrorlab.core.errors import DeviceReplyError, ProtocolError
from mirrorlab.instruments.ultrasonic_tracker import UltrasonicTracker, UltrasonicTrackerModel
from mirrorlab.instruments.ultrasonic_tracker.driver import parse_cycle

from tests.instruments.transcripts import replay_on_model, scripted_driver, transcripts
from tests.tolerances import roundoff

SIMULATOR, DRIVER = transcripts("ultrasonic_tracker.md")


def test_simulator_answers_the_documented_transcript() -> None:
    replay_on_model(UltrasonicTrackerModel(seed=0), SIMULATOR)


def test_driver_sends_the_documented_bytes() -> None:
    with scripted_driver(DRIVER, UltrasonicTracker, "u") as tracker:
        aimed = tracker.aim(0.01, 0.0)
        with pytest.raises(DeviceReplyError, match="E20"):
            tracker.measure()
        reading = tracker.read()
    # parsed from the wire's text and converted to rad: a rounding or two
    assert aimed == pytest.approx((math.radians(0.625), 0.0), rel=roundoff(ops=2))
    np.testing.assert_allclose(reading["direction"], [[math.radians(0.625), 0.0, 133.125, 0, 0, 0]], rtol=roundoff(ops=2))


@pytest.mark.parametrize("line", ["TRK 1 2 3 4", "TRK x 1 2 3 -", "TRK 1 1 2 3 Z", "G 1 1 2 3 -", "TRK 1 a 2 3 L"])
def test_malformed_stream_lines_are_protocol_errors(line: str) -> None:
    with pytest.raises(ProtocolError):
        parse_cycle(line)
