"""FilmScanner driver over a real pty / TCP link to its simulator: settings, units, acquisition
against the film truth, end of film, and a film made from image files."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from mirrorlab.core.devices import SimulatorServer
from mirrorlab.core.errors import ValidationError
from mirrorlab.instruments.film_scanner import FilmScanner
from mirrorlab.instruments.film_scanner.film import PIXEL_MM

from tests.tolerances import roundoff


class Recorder:
    """A stand-in for the session's emitter: collects blocks and truth per frame."""

    def __init__(self, dev: FilmScanner | None = None) -> None:
        self.dev = dev
        self.blocks: dict[str, list[tuple[np.ndarray, np.ndarray]]] = {}
        self.truths: list[list[str]] = []
        self.t0 = time.monotonic()

    def __call__(self, stream: str, times: Any, values: Any) -> None:
        self.blocks.setdefault(stream, []).append((np.asarray(times), np.asarray(values)))
        if stream == "frames" and self.dev is not None:
            # Called between commands from the acquisition thread: the truth of this frame.
            self.truths.append(self.dev.simulate_query("SIM:TRUTH?").data)

    def now(self) -> float:
        return time.monotonic() - self.t0


@pytest.fixture(params=["pty", "tcp"])
def sim(request: pytest.FixtureRequest) -> Iterator[tuple[FilmScanner, SimulatorServer]]:
    settings = {"lines": 280, "threshold": 120}
    with SimulatorServer(FilmScanner.make_simulator(settings, seed=7), request.param) as server:
        dev = FilmScanner("fs", port=server.url, settings=settings)
        dev.connect()
        dev.identify()
        dev.simulate_query("SIM:CLOCK FAST")
        dev.apply_settings(dev.settings)
        yield dev, server
        dev.stop()
        dev.close()


def markers_vs_truth(frame: np.ndarray, truth_lines: list[str]) -> np.ndarray:
    """Detected minus true marker centres (col, row) in px for one scanned frame."""
    rows = [l.split(" ")[1:] for l in truth_lines]
    ys = np.array([float(v) for v in next(r for r in rows if r[0] == "SCAN")[2:]])
    tops = {r[1]: float(r[2]) for r in rows if r[0] == "FRAME"}
    frame_k = min(tops, key=lambda k: abs(tops[k] - ys[0]) if tops[k] <= ys[0] else 1e9)
    true = np.array([[float(r[5]), np.interp(tops[frame_k] + float(r[4]), ys, np.arange(ys.size))]
                     for r in rows if r[0] == "MARKER" and r[1] == frame_k])
    n, _, stats, centres = cv2.connectedComponentsWithStats((frame > 0).astype(np.uint8))
    found = centres[1:][stats[1:, cv2.CC_STAT_AREA] >= 40]
    assert len(found) == len(true)
    return found[np.argsort(found[:, 0])] - true[np.argsort(true[:, 0])]


def test_settings_are_sent_and_validated(sim: tuple[FilmScanner, SimulatorServer]) -> None:
    dev, _ = sim
    assert dev.identity is not None and dev.identity.kind == "FSCAN"
    assert dev.query("THR?").fields == ["120"]
    dev.configure(threshold=90, clock_hz="100 kHz")
    assert dev.query("THR?").fields == ["90"]
    assert dev.line_seconds == pytest.approx(512 / 100e3 + 0.018, rel=roundoff(ops=3))  # the same sum
    with pytest.raises(ValidationError, match="clock_hz"):
        dev.configure(clock_hz=400_000)
    with pytest.raises(ValidationError, match="lines"):
        dev.configure(lines=345)


def test_streams_declared(sim: tuple[FilmScanner, SimulatorServer]) -> None:
    dev, _ = sim
    specs = {s.name: s for s in dev.streams()}
    assert specs["frames"].shape == (280, 512) and specs["frames"].dtype == "u1"
    assert specs["frame_index"].shape == () and specs["frame_index"].dtype == "i8"


def test_operations_in_api_units(sim: tuple[FilmScanner, SimulatorServer]) -> None:
    dev, _ = sim
    # modelled homing time: the search to the switch from where the carrier stands, then the centring
    assert dev.prepare() == pytest.approx(15.2, abs=0.5)
    carrier, film = dev.position()
    assert carrier == pytest.approx(4160 * 0.0046875, rel=roundoff(ops=2)) and film == 0.0  # 4160 steps of 4.6875 um
    lines, seconds = dev.head()
    assert lines > 37 and seconds > 0
    image, seconds = dev.scan(50)
    assert image.shape == (50, 512) and set(np.unique(image)) <= {0, 255}
    # the device reports whole ms: 50 lines of read + feed time to 0.01 s
    assert seconds == pytest.approx(50 * (512 / 73e3 + 0.018), abs=0.01)
    assert dev.feed(-10 * PIXEL_MM) == dev.position()[0]  # both the same integer pointer x 4.6875 um: exact
    assert dev.read_line().shape == (512,)
    assert dev.grey_profile().dtype == np.uint8


def test_acquire_emits_frames_matching_the_film_truth(sim: tuple[FilmScanner, SimulatorServer]) -> None:
    dev, _ = sim
    rec = Recorder(dev)
    dev.start(rec)
    deadline = time.monotonic() + 15
    while len(rec.blocks.get("frame_index", [])) < 2 and time.monotonic() < deadline and dev.running:
        time.sleep(0.05)
    dev.stop()
    assert dev.failed is None, dev.failed
    frames = [v for _, v in rec.blocks["frames"]]
    index = np.concatenate([v for _, v in rec.blocks["frame_index"]])
    assert len(frames) >= 2 and list(index[:2]) == [0, 1]
    times = np.concatenate([t for t, _ in rec.blocks["frames"]])
    assert np.all(np.diff(times) > 0)
    for frame, truth_lines in zip(frames[:2], rec.truths):
        assert frame.shape == (1, 280, 512)
        err = markers_vs_truth(frame[0], truth_lines)
        # binarised blobs (area >= 40 px) under the default faults (feed jitter, vibration): centroids
        # within ~0.5 px, 2 px
        assert np.abs(err).max() < 2.0, err


def test_read_and_end_of_film_with_a_film_of_image_files(tmp_path: Path) -> None:
    for k in range(2):
        img = np.zeros((384, 512), np.uint8)
        cv2.circle(img, (100 + 200 * k, 190), 12, 255, -1)
        cv2.imwrite(str(tmp_path / f"{k}.png"), img)
    settings = {"path": str(tmp_path), "lines": 300}
    with SimulatorServer(FilmScanner.make_simulator(settings, seed=1), "pty") as server:
        dev = FilmScanner("fs", port=server.url, settings=settings)
        events: list[str] = []
        dev.report = lambda level, kind, message, **data: events.append(kind)
        dev.connect()
        dev.simulate_query("SIM:CLOCK FAST")
        first = dev.read()["frames"][0]
        n, _, _, centres = cv2.connectedComponentsWithStats((first > 0).astype(np.uint8))
        assert n == 2 and abs(centres[1][0] - 100) < 2  # a binarised 12 px disc: its centroid within ~0.5 px
        rec = Recorder()
        done = threading.Event()
        dev.acquire(rec, done)                     # frame 1, then E11: returns by itself
        assert len(rec.blocks["frames"]) == 1 and "end_of_film" in events
        dev.close()
