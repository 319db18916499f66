"""FilmScanner with folder / video / camera sources: natural order, pacing, scan geometry,
video decoding and the errors that say what to check."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from mirrorlab.core.errors import ConfigurationError, DeviceDisconnected
from mirrorlab.instruments.film_scanner import FilmScanner
from mirrorlab.instruments.film_scanner.sources import natural_key

from tests.tolerances import roundoff


def disc_frame(x: int, size: tuple[int, int] = (480, 640)) -> np.ndarray:
    img = np.zeros(size, np.uint8)
    cv2.circle(img, (x, size[0] // 2), 40, 255, -1)
    return img


def collect(dev: FilmScanner) -> tuple[list[np.ndarray], list[int], list[float]]:
    frames: list[np.ndarray] = []
    index: list[int] = []
    times: list[float] = []

    def emit(stream: str, t: Any, values: Any) -> None:
        if stream == "frames":
            frames.append(values[0])
            times.append(float(t[0]))
        else:
            index.append(int(values[0]))

    dev.acquire(emit, threading.Event())
    return frames, index, times


def centre_col(frame: np.ndarray) -> float:
    n, _, stats, centres = cv2.connectedComponentsWithStats((frame > 0).astype(np.uint8))
    return float(centres[1 + np.argmax(stats[1:, cv2.CC_STAT_AREA]), 0])


def test_natural_key_orders_numbers() -> None:
    names = ["10.png", "2.png", "frame1.png", "1.png"]
    assert sorted(names, key=lambda n: natural_key(Path(n))) == ["1.png", "2.png", "10.png", "frame1.png"]


def test_folder_source_in_natural_order_and_paced(tmp_path: Path) -> None:
    for name, x in (("10.png", 500), ("2.png", 300), ("1.png", 100)):
        cv2.imwrite(str(tmp_path / name), disc_frame(x))
    (tmp_path / "notes.txt").write_text("not a frame")
    dev = FilmScanner("f", settings={"source": "folder", "path": str(tmp_path), "lines": 300,
                                     "frame_rate": 20.0})
    dev.connect()
    identity = dev.identify()
    assert identity.kind == "FOLDER" and identity.serial == str(tmp_path)
    assert {s.name: s.shape for s in dev.streams()}["frames"] == (300, 512)
    started = time.monotonic()
    frames, index, times = collect(dev)
    assert time.monotonic() - started >= 0.1                     # 3 frames at 20 Hz
    assert index == [0, 1, 2]
    cols = [centre_col(f) for f in frames]
    # 1, 2, 10; a disc resampled 640 -> 512 px and binarised: centroid within ~0.5 px
    assert cols == sorted(cols) and abs(cols[0] - 100 * 512 / 640) < 2
    assert frames[0].shape == (300, 512) and set(np.unique(frames[0])) == {0, 255}
    assert dev.status().connected
    dev.close()


def test_recorded_frames_stamped_at_their_shooting_time(tmp_path: Path) -> None:
    """A consumer slower than the frame rate delays the frames, not their stamps: k / rate from the first."""
    for k in range(4):
        cv2.imwrite(str(tmp_path / f"{k}.png"), disc_frame(100 + 100 * k))
    dev = FilmScanner("f", settings={"source": "folder", "path": str(tmp_path), "frame_rate": 50.0})
    dev.connect()
    times: list[float] = []

    def slow_emit(stream: str, t: Any, values: Any) -> None:
        if stream == "frames":
            times.append(float(t[0]))
            time.sleep(0.05)  # 2.5 frame periods: arrival stamps would be >= 50 ms apart

    dev.acquire(slow_emit, threading.Event())
    dev.close()
    # outside a session the stamps are time.monotonic() seconds (the machine's uptime: 3.6e4 after
    # 10 h, where doubles are 7e-12 apart, 2e-9 after two months), so the differences are exact to the
    # rounding at that magnitude only
    np.testing.assert_allclose(np.diff(times), 0.02, rtol=0, atol=roundoff(scale=max(np.abs(times)), ops=2))


def test_folder_loop_and_read(tmp_path: Path) -> None:
    cv2.imwrite(str(tmp_path / "a.png"), disc_frame(200))
    dev = FilmScanner("f", settings={"source": "folder", "path": str(tmp_path), "loop": True,
                                     "binarise": False, "frame_rate": 1000.0})
    dev.connect()
    assert dev.read()["frames"].shape == (1, 344, 512)
    assert dev.read()["frame_index"][0] == 0                     # read() wraps around
    stop = threading.Event()
    count = []
    dev.start(lambda s, t, v: (count.append(1), len(count) >= 10 and stop.set()))
    deadline = time.monotonic() + 5
    while len(count) < 10 and time.monotonic() < deadline:
        time.sleep(0.01)
    dev.stop()
    assert len(count) >= 10 and dev.failed is None
    dev.close()


def test_folder_errors_say_what_to_check(tmp_path: Path) -> None:
    with pytest.raises(ConfigurationError, match="does not exist"):
        FilmScanner("f", settings={"source": "folder", "path": str(tmp_path / "missing")}).connect()
    with pytest.raises(ConfigurationError, match="holds no PNG"):
        FilmScanner("f", settings={"source": "folder", "path": str(tmp_path)}).connect()
    with pytest.raises(ConfigurationError, match="needs the `path`"):
        FilmScanner("f", settings={"source": "folder"}).connect()


def test_video_source_reads_an_avi(tmp_path: Path) -> None:
    path = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, (640, 480), isColor=False)
    assert writer.isOpened()
    for k in range(5):
        writer.write(disc_frame(100 + 100 * k))
    writer.release()
    dev = FilmScanner("v", settings={"source": "video", "path": str(path), "frame_rate": 1000.0})
    dev.connect()
    assert dev.identify().kind == "VIDEO"
    frames, index, _ = collect(dev)
    assert index == [0, 1, 2, 3, 4]
    expected = [(100 + 100 * k) * 512 / 640 for k in range(5)]
    assert np.allclose([centre_col(f) for f in frames], expected, atol=2.0)  # MJPG blocks, resampling: ~1 px
    dev.close()
    with pytest.raises(ConfigurationError, match="does not exist"):
        FilmScanner("v", settings={"source": "video", "path": str(tmp_path / "none.avi")}).connect()


def test_camera_that_cannot_open_says_what_to_check() -> None:
    with pytest.raises(DeviceDisconnected, match="cannot open camera 63"):
        FilmScanner("c", settings={"source": "camera", "camera_index": 63}).connect()
