"""Virtual lab: rendered markers against the analytic projection, determinism, the FSCAN film and
the direct frame source with its truth in the session file."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from mirrorlab.core import Session
from mirrorlab.core.devices.wire import decode_bits
from mirrorlab.instruments.film_scanner import FilmScannerModel
from mirrorlab.instruments.film_scanner.film import PIXEL_MM
from mirrorlab.instruments.film_scanner.virtual import SOURCE_SIZE, virtual_film
from mirrorlab.instruments.film_scanner.wire import PIXELS
from mirrorlab.instruments.virtual_lab import RenderSettings, make_lab

from tests.tolerances import roundoff


def _polygon_centroid(p: np.ndarray) -> np.ndarray:
    x, y = p[:, 0], p[:, 1]
    x1, y1 = np.roll(x, -1), np.roll(y, -1)
    c = x * y1 - x1 * y
    return np.array([((x + x1) * c).sum(), ((y + y1) * c).sum()]) / (3 * c.sum())


def _intensity_centroid(img: np.ndarray, poly: np.ndarray, background: float) -> np.ndarray:
    lo = np.floor(poly.min(axis=0)).astype(int) - 3
    hi = np.ceil(poly.max(axis=0)).astype(int) + 4
    patch = img[lo[1]:hi[1], lo[0]:hi[0]].astype(float) - background
    yy, xx = np.mgrid[lo[1]:hi[1], lo[0]:hi[0]]
    return np.array([(patch * xx).sum(), (patch * yy).sum()]) / patch.sum()


def test_rendered_marker_centres_match_the_analytic_projection() -> None:
    lab = make_lab("rssr", settings=RenderSettings(background=0.0), distortion=(-0.08, 0.02, 0.0, 0.0, 0.0))
    times = np.linspace(0.0, 10.0, 5)
    truth = lab.truth(times)
    xy, _ = truth.view_xy()
    render_err, total_err = [], []
    for k in range(times.size):
        img = lab.render_truth(truth, k)
        o = lab.outlines(truth, k)
        assert o.polygons.shape[0] == 4                                   # 2 markers x (direct + mirror)
        for poly, view, m in zip(o.polygons, o.view, o.marker):
            c = _intensity_centroid(img, poly, 0.0)
            render_err.append(c - _polygon_centroid(poly))
            total_err.append(c - xy[k, view + 1, m])
    render_err, total_err = np.array(render_err), np.array(total_err)
    # rasterisation (render.py): cv2.fillPoly on 8 x 8 sub-pixels with its edge rule, vertices to 1/128
    # px, coverage in steps of 1/255: ~0.01 px at 10 px radius; integer arithmetic, the same on every CPU
    assert np.sqrt((render_err**2).mean()) < 0.01 and np.abs(render_err).max() < 0.03
    # plus the perspective offset of the ellipse centre, <= f r^2 / (2 Z^2) ~ 0.05 px (f = 1500 px,
    # r = 10 mm, Z ~ 1.2 m)
    assert np.abs(total_err).max() < 0.1


def test_frames_are_deterministic_with_a_seed() -> None:
    look = RenderSettings(blur_sigma=1.2, noise_sigma=2.0, illumination=0.3, clutter=15, seed=7)
    lab = make_lab("upper_limb", image_size=(640, 480), settings=look)
    a = [f for _, f in lab.frames([0.0, 0.4])]
    b = [f for _, f in make_lab("upper_limb", image_size=(640, 480), settings=look).frames([0.0, 0.4])]
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not np.array_equal(lab.render(0.0, index=0), lab.render(0.0, index=1))     # fresh noise
    other = lab.with_settings(seed=8)
    assert not np.array_equal(other.render(0.0), lab.render(0.0))
    clean = make_lab("upper_limb", image_size=(640, 480)).render(0.0)
    assert np.unique(clean).size > 2 and clean.min() == 12                           # dark background




def test_film_of_lab_frames_scanned_by_fscan_shows_the_markers() -> None:
    film = virtual_film("rssr", 3.0, 1)
    model = FilmScannerModel(film, seed=3)
    for cmd in ("SIM:CLOCK FAST", "CLAMP BASE", "HOME", "CLAMP CARRIER", "HEAD"):
        assert model.execute(cmd)[-1].startswith("OK"), cmd
    lines = model.execute("SCAN 344")
    image = np.array([decode_bits(line.split()[2], PIXELS) for line in lines[:-1]], dtype=np.uint8)
    n, _, stats, centres = cv2.connectedComponentsWithStats(image)
    blobs = centres[1:][stats[1:, cv2.CC_STAT_AREA] >= 10]
    truth = sorted(film.markers, key=lambda mk: mk.col_px)
    assert len(blobs) == len(truth) == 4
    cols = np.sort(blobs[:, 0])
    # binarised discs of 16-120 px area: thresholding moves an edge by up to half a pixel, so a blob's
    # centroid is within ~0.5 px of its centre; 2 px (columns) and 3 px (with the fed line positions)
    assert np.abs(cols - [mk.col_px for mk in truth]).max() < 2.0
    scan_y = np.array([float(v) for v in next(x for x in model.truth_lines() if x.startswith("SCAN ")).split()[2:]])
    top = film.frame_top_mm(0)
    for mk in truth:                               # the row the marker was scanned at, from the true line positions
        row = np.interp(top + mk.y_mm, scan_y, np.arange(scan_y.size))
        d = np.hypot(blobs[:, 0] - mk.col_px, blobs[:, 1] - row)
        assert d.min() < 3.0
    assert PIXEL_MM > 0


def test_virtual_source_records_frames_and_truth(tmp_path: Path) -> None:
    settings = {"source": "virtual", "scene": "rssr", "frame_rate": 50.0, "scene_frames": 6, "binarise": False,
                "lines": 344}
    with Session.create(tmp_path / "v.h5", operator="t", description="virtual lab") as s:
        s.add_instrument("cam", "film_scanner", settings=settings)
        s.record(0.6)                               # the recording_stopped hook writes /truth/cam
        times, frames = s.stream("cam", "frames")
        index = s.stream("cam", "frame_index").data
        truth = s.truth("cam")
        assert truth["markers/frame_index"].tolist() == index.tolist() == list(range(6))
        real = truth["markers/real_xy"]
        assert real.shape == (6, 2, 2) and truth["markers/virtual_xy"].shape == (6, 1, 2, 2)
        np.testing.assert_allclose(truth["markers/time"], index / 50.0, rtol=0, atol=roundoff(scale=index.max() / 50.0, ops=2))
        assert truth["analytic/phi"].shape == (6,)
        # each true direct image (1024 x 768 render -> 512 x 384 scan, central 344 lines) is bright:
        # markers at grey 235 on 12, their centre pixel stays far above 150 after the 2x reduction
        top = (384 - 344) // 2
        for k in range(6):
            for x, y in real[k]:
                col = (x + 0.5) * 512 / SOURCE_SIZE[0] - 0.5
                row = (y + 0.5) * 384 / SOURCE_SIZE[1] - 0.5 - top
                assert frames[k, int(round(row)), int(round(col))] > 150
