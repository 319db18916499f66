"""Chunks of frames merged in frame order equal one run on all frames (pure functions, property tests)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from mirrorlab.core.batch.chunks import chunk_bounds, merge_frames
from mirrorlab.plugins.markers.stream import detect_stream


@given(st.integers(0, 500), st.integers(1, 64))
def test_bounds_cover_every_frame_once_in_order(frames: int, size: int) -> None:
    bounds = chunk_bounds(frames, size)
    covered = [f for a, b in bounds for f in range(a, b)]
    assert covered == list(range(frames))
    assert all(0 < b - a <= size for a, b in bounds)


def test_bounds_refuse_an_empty_chunk() -> None:
    with pytest.raises(ValueError, match="at least 1 frame"):
        chunk_bounds(10, 0)


def _frames(counts: list[int], seed: int) -> np.ndarray:
    """Frames with ``counts[f]`` separate bright 3x3 squares at random places (markers to detect)."""
    rng = np.random.default_rng(seed)
    frames = np.zeros((len(counts), 40, 64), np.uint8)
    for f, n in enumerate(counts):
        cells = rng.choice(6 * 10, size=n, replace=False)
        for c in cells:
            y, x = 3 + 6 * (c // 10), 3 + 6 * (c % 10)
            frames[f, y:y + 3, x:x + 3] = rng.integers(150, 256)
    return frames


@given(st.lists(st.integers(0, 5), min_size=1, max_size=12), st.integers(1, 5), st.integers(0, 2**16))
def test_chunked_detection_equals_detection_of_all_frames(counts: list[int], size: int, seed: int) -> None:
    """Ragged marker counts: narrower chunks are NaN-padded; the merge is the serial result bit for bit."""
    frames = _frames(counts, seed)
    whole = vars(detect_stream(frames))
    parts = [vars(detect_stream(frames[a:b])) for a, b in chunk_bounds(len(frames), size)]
    merged = merge_frames(parts)
    assert whole["counts"].tolist() == counts
    for name, value in whole.items():
        assert merged[name].dtype == value.dtype and merged[name].shape == value.shape, name
        assert merged[name].tobytes() == value.tobytes(), name


def test_ragged_integer_output_needs_a_declared_fill() -> None:
    parts = [{"index": np.zeros((1, 1), np.int64)}, {"index": np.zeros((1, 2), np.int64)}]
    with pytest.raises(ValueError, match="'index'.*frame_fill"):
        merge_frames(parts)
    assert merge_frames(parts, {"index": -1})["index"].tolist() == [[0, -1], [0, 0]]


def test_scalar_output_cannot_be_merged() -> None:
    with pytest.raises(ValueError, match="'rms' is not an array over frames"):
        merge_frames([{"rms": np.float64(1.0)}, {"rms": np.float64(2.0)}])
