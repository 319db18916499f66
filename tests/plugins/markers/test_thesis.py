"""The thesis detector against a literal per-pixel reading of spec §1.1, and its documented limits."""

from __future__ import annotations

import numpy as np
import pytest
from mirrorlab.plugins.markers import DEFAULT_WEIGHTS, InvalidDetectionParameter, detect_markers, thesis_centres

from .render import binary_disc_frame


def reference_thesis(binary: np.ndarray, w: np.ndarray = DEFAULT_WEIGHTS) -> list[list[float]]:
    """Steps 1–4 written out pixel by pixel, straight from the spec text (slow; small images only)."""
    b = (np.asarray(binary) != 0).astype(int)
    h, wd = b.shape

    def px(x: int, y: int) -> int:
        return int(b[y, x]) if 0 <= x < wd and 0 <= y < h else 0

    def row_window(x: int, y: int) -> int:
        return sum(int(w[j]) * px(x - 11 + j, y) for j in range(24))

    def col_window(x: int, y: int) -> int:
        return sum(int(w[j]) * px(x, y - 11 + j) for j in range(24))

    def r_h(x: int, y0: int) -> int:
        total, y = 0, y0
        while (s := row_window(x, y)) != 0:
            total, y = total + s, y + 1
        return total

    def r_v(y: int, xc: int) -> int:
        total, x = 0, xc
        while (s := col_window(x, y)) != 0:
            total, x = total + s, x + 1
        x = xc - 1
        while (s := col_window(x, y)) != 0:
            total, x = total + s, x - 1
        return total

    out = []
    for y0 in range(8, h - 12):
        x = 8
        while x <= wd - 13:
            if not b[y0, x]:
                x += 1
                continue
            x0 = x
            xc, best = x0, r_h(x0, y0)
            step = 1 if r_h(x0 + 1, y0) > best else -1
            while r_h(xc + step, y0) > best:
                xc, best = xc + step, r_h(xc + step, y0)
            yc, best = y0, r_v(y0, xc)
            while r_v(yc + 1, xc) > best:
                yc, best = yc + 1, r_v(yc + 1, xc)
            out.append([xc + 0.5, yc + 0.5])
            b[max(yc - 11, 0):yc + 13, max(xc - 11, 0):xc + 13] = 0
            x = xc + 13
    return out


@pytest.mark.parametrize("seed", range(6))
def test_vectorised_detector_equals_the_literal_reading(seed: int) -> None:
    rng = np.random.default_rng(seed)
    shape = (70, 90)
    centres = rng.uniform([12, 12], [78, 58], size=(4, 2))
    b = binary_disc_frame(shape, centres, rng.uniform(2.5, 8.0, 4)) > 0
    b |= rng.random(shape) < 0.01  # isolated noise pixels
    weights = DEFAULT_WEIGHTS if seed % 2 == 0 else rng.integers(0, 40, 24)
    xy, _ = thesis_centres(b, weights, weights)
    assert xy.tolist() == reference_thesis(b, weights)


def test_output_is_window_index_plus_half_and_symmetric_blobs_are_centred() -> None:
    b = np.zeros((60, 60), np.uint8)
    b[20:30, 30:40] = 1  # even width: centre (34.5, 24.5) exactly
    assert thesis_centres(b)[0].tolist() == [[34.5, 24.5]]


def test_limit_markers_closer_than_13_px_on_one_row_are_lost() -> None:
    frame = binary_disc_frame((80, 120), np.array([[50.0, 40.0], [60.0, 40.0]]), 3.0)
    assert len(detect_markers(frame, method="thesis")) == 1
    assert len(detect_markers(frame, method="subpixel")) == 2


def test_limit_markers_near_the_border_are_not_searched() -> None:
    frame = binary_disc_frame((80, 120), np.array([[5.0, 40.0], [60.0, 40.0]]), 2.0)
    found = detect_markers(frame, method="thesis").xy
    # integer window index + 0.5: half a pixel of quantisation plus the 2 px disc's sampled asymmetry
    assert len(found) == 1 and abs(found[0, 0] - 60.0) <= 1.0
    assert len(detect_markers(frame, method="subpixel")) == 2


def test_limit_markers_larger_than_24_px_are_split() -> None:
    frame = binary_disc_frame((120, 160), np.array([[80.0, 60.0]]), 20.0)
    assert len(detect_markers(frame, method="thesis")) > 1
    assert len(detect_markers(frame, method="subpixel")) == 1


def test_limit_plateaus_stop_the_climb() -> None:
    """Flat weights make R_H constant while the window covers the whole marker: the climb never starts."""
    b = np.zeros((60, 60), np.uint8)
    b[20:26, 20:26] = 1  # 6 px square, centre (22.5, 22.5)
    flat = np.ones(24, int)
    xy, _ = thesis_centres(b, flat, flat)
    assert xy.tolist() == [[20.5, 20.5]]  # stays at the start (x0, y0) + 0.5
    assert thesis_centres(b)[0].tolist() == [[22.5, 22.5]]


@pytest.mark.parametrize("bad", [np.ones(23), -np.ones(24), np.full(24, 0.5), np.zeros(24)])
def test_bad_weights_are_rejected(bad: np.ndarray) -> None:
    with pytest.raises(InvalidDetectionParameter, match="weights_h"):
        thesis_centres(np.zeros((40, 40)), bad)
