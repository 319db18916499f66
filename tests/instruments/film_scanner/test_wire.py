"""The FSCAN wire format, pinned by the transcripts of docs/instruments/film_scanner.md.

The first transcript is replayed on the simulator as ``mirrorlab simulate film_scanner --set
scene_frames=1`` makes it (byte-identical replies for seed 0); the second is served by a scripted
device on a real pty to the real driver, which must send exactly its bytes and turn the replies
into frames (0/255 per pixel), positions (mm) and the end of the film.
"""

from __future__ import annotations

import numpy as np
import pytest
from mirrorlab.core.errors import DeviceDisconnected
from mirrorlab.instruments.film_scanner import FilmScanner
from mirrorlab.instruments.film_scanner.mechanics import STEP_UM

from tests.instruments.transcripts import replay_on_model, scripted_driver, transcripts

SIMULATOR, DRIVER = transcripts("film_scanner.md")
MARKER_PIXELS = list(range(123, 134))   # "1FFC" from hex digit 30: bits 123...133 of the line


def test_simulator_answers_the_documented_transcript() -> None:
    model = FilmScanner.make_simulator({"scene_frames": 1}, seed=0)
    replay_on_model(model, SIMULATOR)


def test_driver_sends_the_documented_bytes() -> None:
    events: list[tuple[str, str, str]] = []
    with scripted_driver(DRIVER, FilmScanner, "fs", {"lines": 2}) as scanner:
        scanner.report = lambda level, kind, text, **_: events.append((level, kind, text))
        first = scanner.read()
        line = scanner.read_line()
        carrier_mm, film_mm = scanner.position()
        fed_mm = scanner.feed(1.0)               # 1.0 mm / 46.875 um = 21.3: 21 lines
        with pytest.raises(DeviceDisconnected, match="no frame to read"):
            scanner.read()                       # HEAD answers E11: the end of the film
    frames = first["frames"]
    assert frames.shape == (1, 2, 512) and first["frame_index"].tolist() == [0]
    assert not frames[0, 0].any() and np.flatnonzero(frames[0, 1]).tolist() == MARKER_PIXELS
    assert set(np.unique(frames)) == {0, 255}
    assert np.flatnonzero(line).tolist() == MARKER_PIXELS
    # steps times the step (4.6875 um, exact in binary) over 1000: one rounding each
    assert (carrier_mm, film_mm, fed_mm) == pytest.approx((4180 * STEP_UM / 1000, 1250 * STEP_UM / 1000,
                                                           4390 * STEP_UM / 1000), rel=1e-15)
    assert [kind for _, kind, _ in events] == ["end_of_film"]
