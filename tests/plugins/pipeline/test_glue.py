"""The pipeline glue against ground truth: grid matching, camera projection, view split, epipole,
pairing + tracking carried to (F, T, 2) arrays, marker labelling."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.core import ValidationError
from mirrorlab.core.algorithms import execute
from mirrorlab.instruments.virtual_lab import make_lab
from mirrorlab.plugins.pairing import mirror_epipole
from mirrorlab.plugins.pairing.algorithms import PairMirror
from mirrorlab.plugins.photogrammetry import PinholeCamera, fit_plane_calibration
from mirrorlab.plugins.photogrammetry.camera_arrays import plane_arrays
from mirrorlab.plugins.pipeline import (
    EpipoleError,
    GridMatchError,
    ViewSplitError,
    assign_views,
    camera_projection,
    estimate_epipole,
    match_grid,
    mirror_outline,
    mirror_tracks,
    split_views,
)
from mirrorlab.plugins.pipeline.algorithms import LabSurvey, RSSRMarkers, SurveyError
from mirrorlab.plugins.pipeline.epipole import _SCORE_BLOCK
from mirrorlab.plugins.tracking import track

from tests.plugins.photogrammetry.bounds import normal_condition
from tests.tolerances import roundoff

SIZE = (1024, 768)


def dlt_condition(src: np.ndarray, dst: np.ndarray) -> float:
    """sigma_1 / sigma_8 of the normalised DLT matrix of src -> dst (its null vector is the homography:
    the homography's relative error is ~ that times eps)."""
    def norm(p: np.ndarray) -> np.ndarray:
        c = p - p.mean(axis=0)
        return c * np.sqrt(2.0) / np.linalg.norm(c, axis=1).mean()

    a, b = np.c_[norm(src), np.ones(len(src))], np.c_[norm(dst), np.ones(len(dst))]
    A = np.zeros((2 * len(a), 9))
    A[0::2, 0:3], A[0::2, 6:9] = a, -b[:, :1] * a
    A[1::2, 3:6], A[1::2, 6:9] = a, -b[:, 1:2] * a
    s = np.linalg.svd(A, compute_uv=False)
    return float(s[0] / s[7])


def epipole_roundoff(real: np.ndarray, virtual: np.ndarray) -> float:
    """Rounding bound of the unit homogeneous epipole from exact (real, virtual) pairs: the null vector
    of the lines through each pair, as the mirror normal from ray pairs (tests/plugins/photogrammetry/bounds.py)."""
    ph = np.c_[real.reshape(-1, 2), np.ones(real[..., 0].size)]
    qh = np.c_[virtual.reshape(-1, 2), np.ones(virtual[..., 0].size)]
    return roundoff(cond=normal_condition(ph, qh), ops=10)


# ------------------------------------------------------------------------------------------- grid matching
def test_grid_on_exact_projections_recovers_identity() -> None:
    lab = make_lab("grid", image_size=SIZE)
    tr = lab.truth([0.0])
    vis = tr.real_visible[0]
    xy, world = tr.real_xy[0][vis], tr.positions[0][vis]
    rng = np.random.default_rng(3)
    order = rng.permutation(len(xy))
    xy, world = xy[order], world[order]
    a, b = 100, 400
    refs = [[*world[a, :2], *np.round(xy[a])], [*world[b, :2], *np.round(xy[b])]]
    m = match_grid(xy, 60.0, refs)
    assert len(m.blob_index) == len(xy)                                # every visible disc
    assert np.array_equal(m.plane_xy, world[m.blob_index, :2])          # exactly its grid point
    assert np.array_equal(m.lattice * 60, world[m.blob_index, :2])
    # a homography, no distortion: exact to the DLT's rounding, condition sigma_1 / sigma_8, in pixels
    assert m.residual.max() <= roundoff(cond=dlt_condition(m.plane_xy, xy[m.blob_index]), scale=max(SIZE), ops=10)


@settings(max_examples=25, deadline=None)
@given(angle=st.floats(0, 2 * np.pi), scale=st.floats(12, 30), px=st.floats(-2e-4, 2e-4),
       py=st.floats(-2e-4, 2e-4), ox=st.integers(-5, 5), oy=st.integers(-5, 5), seed=st.integers(0, 1000))
def test_grid_matching_property(angle: float, scale: float, px: float, py: float, ox: int, oy: int,
                                seed: int) -> None:
    """Any rotation, scale and mild perspective (camera on the +Z side): the numbering is exact."""
    i, j = np.meshgrid(np.arange(-15, 16), np.arange(-15, 16), indexing="ij")
    plane = np.c_[i.ravel(), j.ravel()] * 60.0 + [ox * 60.0, oy * 60.0]
    c, s = np.cos(angle), np.sin(angle)
    k = scale / 60.0
    A = np.array([[c * k, s * k, 320.0], [s * k, -c * k, 240.0], [0.0, 0.0, 1.0]])   # y-down: right-handed
    H = A @ np.array([[1.0, 0.0, -ox * 60.0], [0.0, 1.0, -oy * 60.0], [px, py, 1.0]])
    img = np.c_[plane, np.ones(len(plane))] @ H.T
    ok = img[:, 2] > 0.2
    img = img[:, :2] / np.where(ok, img[:, 2], 1.0)[:, None]
    ok &= (img[:, 0] > 5) & (img[:, 0] < 635) & (img[:, 1] > 5) & (img[:, 1] < 475)
    img, plane = img[ok], plane[ok]
    rng = np.random.default_rng(seed)
    a, b = rng.choice(len(img), 2, replace=False)
    m = match_grid(img, 60.0, [[*plane[a], *img[a]], [*plane[b], *img[b]]])
    assert np.array_equal(m.plane_xy, plane[m.blob_index])
    assert len(m.blob_index) == len(img)


def test_grid_errors_are_specific() -> None:
    with pytest.raises(GridMatchError, match="only 3 blobs"):
        match_grid(np.zeros((3, 2)), 60.0, [[0, 0, 0, 0], [60, 0, 1, 0]])
    g = np.mgrid[0:6, 0:5].reshape(2, -1).T * 20.0 + 50.0
    with pytest.raises(GridMatchError, match="reference 1"):
        match_grid(g, 60.0, [[0, 0, 50, 50], [60, 0, 300, 300]])
    with pytest.raises(GridMatchError, match="whole number of pitches"):
        match_grid(g, 60.0, [[0, 0, 50, 50], [30, 0, 70, 50]])


# ------------------------------------------------------------------------------------------- camera projection
def test_plane_map_projection_equals_pinhole() -> None:
    lab = make_lab("rssr", image_size=SIZE)
    cam = lab.camera
    g = np.mgrid[-10:11, -8:9].reshape(2, -1).T * 60.0 - [150.0, 60.0]
    plane = np.c_[g, np.zeros(len(g))]
    cal = fit_plane_calibration(cam.project(plane), g, 0.0, cam.camera_center, model="projective")
    P = camera_projection(plane_arrays(cal))
    rng = np.random.default_rng(0)
    X = rng.uniform([-400, -400, 0], [400, 400, 900], (50, 3))
    Xh = np.c_[X, np.ones(50)]
    x = Xh @ P.T
    assert np.all(x[:, 2] > 0)
    # P's entries carry the fit's relative error kappa eps (kappa = cal.condition); a projection moves
    # by that times its componentwise magnitude (|P| |X| over the depth, numerator and denominator)
    u = x[:, :2] / x[:, 2:]
    mag = np.abs(Xh) @ np.abs(P.T)
    reach = np.max((mag[:, :2] + np.abs(u) * mag[:, 2:]) / x[:, 2:])
    assert np.abs(u - cam.project(X)).max() <= roundoff(cond=cal.condition, scale=reach, ops=10)


# ------------------------------------------------------------------------------------------- split, pair, track
@pytest.fixture(scope="module")
def rssr_truth():
    lab = make_lab("rssr", image_size=SIZE)
    return lab, lab.truth(np.arange(20) / 3.0)


def _shuffled_detections(truth, seed: int = 7) -> np.ndarray:
    both = np.concatenate([truth.real_xy, truth.virtual_xy[:, 0]], axis=1)            # (F, 2M, 2)
    rng = np.random.default_rng(seed)
    det = np.stack([frame[rng.permutation(len(frame))] for frame in both])
    return np.concatenate([det, np.full((len(det), 1, 2), np.nan)], axis=1)            # a padding row


def test_split_pair_track_recovers_truth_exactly(rssr_truth) -> None:
    lab, tr = rssr_truth
    det = _shuffled_detections(tr)
    c = lab.camera
    P = camera_projection(PinholeCamera(c.K, c.dist, c.R, c.t, c.image_size))   # the lab's camera, as calibrated
    outline = mirror_outline(P, lab.mirrors[0].corners())
    virt, vm, vrow, view = split_views(det, [outline])
    # every true mirror image is a candidate (direct images may be too: the mechanism is in front of the mirror)
    for f in range(len(det)):
        cand = {tuple(p) for p in virt[f][np.isfinite(virt[f, :, 0])]}
        assert {tuple(p) for p in tr.virtual_xy[f, 0]} <= cand
    est = estimate_epipole(det, virt)
    true_e = mirror_epipole(P, lab.camera.camera_center, lab.mirrors[0].centre, lab.mirrors[0].normal)
    # same point, same sign, to the rounding of the line intersection
    assert np.abs(est.epipole - true_e).max() <= epipole_roundoff(tr.real_xy, tr.virtual_xy[:, 0])
    out = execute(PairMirror, {"real": det, "virtual": virt, "epipoles": est.epipole[None]}, {"tol": 0.5})
    assert out.status == "ok" and out.outputs["n_ambiguous"].sum() == 0
    real, paired, rows, role = assign_views(det, vrow, out.outputs["virtual_index"], out.outputs["virtual_xy"])
    tracks = track(real)
    r, v = mirror_tracks(real, tracks.index, paired)
    assert r.shape == (20, 2, 2)
    for t in range(2):
        m = int(np.argmin(np.abs(tr.real_xy[0] - r[0, t]).sum(axis=1)))
        assert np.array_equal(r[:, t], tr.real_xy[:, m])                    # exactly the truth
        assert np.array_equal(v[:, t], tr.virtual_xy[:, 0, m])


def test_estimate_epipole_needs_two_frames() -> None:
    with pytest.raises(EpipoleError, match="at least two frames"):
        estimate_epipole(np.zeros((1, 2, 2)), np.ones((1, 2, 2)))


def test_glue_shape_errors_name_the_shapes() -> None:
    with pytest.raises(ViewSplitError, match=r"\(F, K, 2\)"):
        split_views(np.zeros((3, 2)), [])
    with pytest.raises(ViewSplitError, match="track_index refers to detection 5"):
        mirror_tracks(np.zeros((1, 2, 2)), [[5]], np.zeros((1, 2, 1, 2)))
    with pytest.raises(ViewSplitError, match="behind the camera"):
        mirror_outline(np.c_[np.eye(3), np.zeros(3)], [[0, 0, -1], [1, 0, -1], [1, 1, -1]])


def test_assign_views_mirror_image_never_direct() -> None:
    # detection 1 is the mirror image of 0 and was itself paired (wrongly) with 2: it stays a mirror image
    xy = np.array([[[0.0, 0.0], [5.0, 0.0], [8.0, 0.0]]])
    vi = np.array([[[0], [1], [-1]]])            # candidates: row 1, row 2
    pv = np.full((1, 3, 1, 2), np.nan)
    pv[0, 0, 0], pv[0, 1, 0] = xy[0, 1], xy[0, 2]
    real, paired, rows, role = assign_views(xy, [[1, 2]], vi, pv)
    assert role.tolist() == [[-1, 0, 0]]
    assert rows.tolist() == [[0]] and paired[0, 0, 0].tolist() == [5.0, 0.0]


# ------------------------------------------------------------------------------------------- survey, labels
def test_lab_survey_and_errors() -> None:
    out = execute(LabSurvey, {}, {"camera_center": "1, 2, 3", "mirror_corners": "0,0,0; 2,0,0; 2,2,0; 0,2,0"})
    assert out.status == "ok" and out.outputs["mirror_point"].tolist() == [1.0, 1.0, 0.0]
    with pytest.raises(ValidationError, match=r"camera_center: expected 3 values \(float\[3\] in mm\), got 2"):
        execute(LabSurvey, {}, {"camera_center": "1, 2", "mirror_corners": "0,0,0; 2,0,0; 2,2,0"})
    bad = execute(LabSurvey, {}, {"camera_center": "[1, 2, 3] m", "mirror_corners": "0,0,0; 2,0,0"})
    assert bad.status == "failed" and "mirror_corners needs at least 3 corners" in bad.error
    assert issubclass(SurveyError, ValueError)


def test_rssr_markers_labels_joints_and_frame_period(rssr_truth) -> None:
    lab, tr = rssr_truth
    pts = tr.positions[:, ::-1]                                           # tracks in the other order
    stamps = 100.0 + np.arange(20) / 3.0 + np.r_[0.05, np.zeros(19)]     # a late first frame
    out = execute(RSSRMarkers, {"points": pts, "time": stamps, "frame_index": np.arange(20)},
                  {"O_A": "300, -100, 700", "e": "0, 0, 1", "crank": 61.0})
    assert out.status == "ok"
    assert out.outputs["tracks"].tolist() == [1, 0]
    assert np.array_equal(out.outputs["S_A"], tr.positions[:, 0])
    # stamps of ~107 s a third of a second apart: each step is good to eps |t| / (1/3), ~320 eps
    kappa = stamps.max() / (1 / 3)
    assert abs(out.outputs["frame_period"] - 1 / 3) <= roundoff(cond=kappa, scale=1 / 3, ops=4)
    np.testing.assert_allclose(out.outputs["time"], tr.time, rtol=0, atol=roundoff(cond=kappa, scale=20 / 3, ops=4))


@settings(max_examples=30, deadline=None)
@given(ex=st.floats(-3000, 3000), ey=st.floats(-3000, 3000), front=st.booleans(), seed=st.integers(0, 10_000))
def test_estimate_epipole_property(ex: float, ey: float, front: bool, seed: int) -> None:
    """Exact pairs of 3 markers over 6 frames, mirror images listed in random order: e found, sign kept."""
    rng = np.random.default_rng(seed)
    e = np.array([ex, ey])
    p = rng.uniform(0, 600, (6, 3, 2))
    s = rng.uniform(0.1, 0.5, (6, 3, 1))
    q = p + s * (e - p) if front else p - s * (e - p)       # between p and e, or beyond p
    bound = epipole_roundoff(p, q)
    q = np.stack([frame[rng.permutation(3)] for frame in q])
    est = estimate_epipole(p, q, tol=1e-3)
    truth = np.r_[e, 1.0] * (1 if front else -1)
    truth /= np.linalg.norm(truth)
    assert np.abs(est.epipole - truth).max() <= bound
    assert est.inliers >= 18


def test_estimate_epipole_memory_does_not_grow_with_the_square_of_the_pairs() -> None:
    """A long recording (8000 frames, 16 000 true pairs): the refinement and the scoring never hold an
    inliers x inliers or candidates x combinations array (an n x n float64 factor alone would be 2 GB); the
    peak stays a fixed block plus arrays linear in the combinations."""
    rng = np.random.default_rng(3)
    e = np.array([900.0, -400.0])
    p = rng.uniform(0, 600, (8000, 2, 2))
    q = p + rng.uniform(0.1, 0.5, (8000, 2, 1)) * (e - p)
    combinations = p.shape[0] * p.shape[1] * q.shape[1]
    tracemalloc.start()
    try:
        est = estimate_epipole(p, q, samples=200, tol=1e-3)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert est.inliers == 16_000
    n_by_n = est.inliers**2 * 8
    # the scoring block's temporaries (a dozen float64 arrays of _SCORE_BLOCK) and ~40 float64 per combination
    assert peak < 12 * 8 * _SCORE_BLOCK + 40 * 8 * combinations < n_by_n / 4, (peak, n_by_n)
