"""Fuzz the film scanner's folder source with cut and bit-flipped PNG/JPEG frames.

Reading gives a greyscale frame or a :class:`DataError` naming the file, nothing else; recorded
through the instrument's acquisition thread, a damaged frame stops that source once, without
reconnecting (frame indices never repeat) and without hanging.
"""

from __future__ import annotations

import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirrorlab.core.errors import DataError
from mirrorlab.instruments.film_scanner import FilmScanner
from mirrorlab.instruments.film_scanner.sources import FolderSource

from tests.strategies import damaged, fuzz

#: A small chessboard view with grey levels and blur like a photograph's (small so that decoding is
#: quick), as a baseline JPEG and a PNG: the folder source must survive any damage to either.
_board = cv2.GaussianBlur(np.kron((np.indices((9, 16)).sum(axis=0) % 2) * 160 + 40, np.ones((10, 10))).astype(np.uint8),
                          (5, 5), 1.5)
FRAMES = {".jpg": cv2.imencode(".jpg", _board)[1].tobytes(), ".png": cv2.imencode(".png", _board)[1].tobytes()}


@pytest.fixture(scope="module")
def workdir() -> Iterator[Path]:
    with tempfile.TemporaryDirectory() as name:
        yield Path(name)


@st.composite
def damaged_folder(draw: st.DrawFn) -> tuple[str, bytes]:
    suffix = draw(st.sampled_from(sorted(FRAMES)))
    return suffix, draw(damaged(FRAMES[suffix], hot=200))


def write_folder(root: Path, suffix: str, bad: bytes) -> Path:
    """Frames 0 and 2 intact, frame 1 damaged (a fresh folder per example)."""
    folder = Path(tempfile.mkdtemp(dir=root))
    for k in range(3):
        (folder / f"{k}{suffix}").write_bytes(bad if k == 1 else FRAMES[suffix])
    return folder


@pytest.mark.timeout(120)
@fuzz(150)
@given(case=damaged_folder())
def test_reading_a_damaged_frame(workdir: Path, case: tuple[str, bytes]) -> None:
    suffix, bad = case
    source = FolderSource(write_folder(workdir, suffix, bad))
    source.open()
    assert source.read()[0] == 0
    try:
        index, img = source.read()
    except DataError as exc:
        assert f"1{suffix}" in str(exc) and "replace or remove it" in str(exc)
    else:
        assert index == 1 and img.ndim == 2 and img.dtype == np.uint8 and img.size > 0


@pytest.mark.timeout(120)
@fuzz(40)
@given(case=damaged_folder())
def test_recording_a_damaged_frame_never_reconnects(workdir: Path, case: tuple[str, bytes]) -> None:
    suffix, bad = case
    events: list[tuple[str, str]] = []
    dev = FilmScanner("cam", settings={"source": "folder", "path": str(write_folder(workdir, suffix, bad)),
                                       "frame_rate": 1000.0, "lines": 8},
                      report=lambda level, kind, message, **data: events.append((kind, message)))
    dev.connect()
    dev.identify()
    indices: list[int] = []

    def emit(stream: str, times: Any, values: Any) -> None:
        if stream == "frame_index":
            indices.extend(int(v) for v in values)

    try:
        dev.start(emit)
        thread = dev._thread
        assert thread is not None
        thread.join(timeout=60.0)  # generous: only a hang gets near it
        assert not thread.is_alive(), "the acquisition thread hangs"
    finally:
        dev.stop()
        dev.close()
    assert dev.reconnects == 0 and not any(kind == "connection_lost" for kind, _ in events)
    if dev.failed is None:
        assert indices == [0, 1, 2]
    else:
        assert isinstance(dev.failed, DataError) and indices == [0]
        assert [k for k, _ in events if k != "state"] == ["failed"]  # state changes aside
        assert any(f"1{suffix}" in m for k, m in events if k == "failed")
