"""The OLDT wire format, pinned by the transcripts of docs/instruments/line_tracker.md.

The first transcript is replayed on the simulator (byte-identical replies and stream lines for
seed 0); the second is served by a scripted device on a real pty to the real driver, which must
send exactly its bytes.
"""

from __future__ import annotations

import numpy as np
import pytest
from mirrorlab.core.errors import ProtocolError
from mirrorlab.instruments.line_tracker import LineTracker, LineTrackerModel
from mirrorlab.instruments.line_tracker.driver import parse_mark

from tests.instruments.transcripts import replay_on_model, scripted_driver, transcripts

SIMULATOR, DRIVER = transcripts("line_tracker.md")


def test_simulator_answers_the_documented_transcript() -> None:
    replay_on_model(LineTrackerModel(seed=0), SIMULATOR)


def test_driver_sends_the_documented_bytes() -> None:
    with scripted_driver(DRIVER, LineTracker, "l") as tracker:
        first, second = tracker.read()["mark"], tracker.read()["mark"]
        runs = tracker.runs()
    np.testing.assert_array_equal(first, [[255.5, 62, 128, 1]])
    assert np.isnan(second[0, [0, 1, 3]]).all() and second[0, 2] == 128
    np.testing.assert_array_equal(runs, [[115, 176], [336, 394]])


@pytest.mark.parametrize("line", ["M 1 2 3 4", "M x 1 2 3 1", "M 1 1 2 3.5 1", "G 1 1 2 3 1", "M 1 a 2 3 1"])
def test_malformed_stream_lines_are_protocol_errors(line: str) -> None:
    with pytest.raises(ProtocolError):
        parse_mark(line)
