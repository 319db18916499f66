"""Real/mirror pairing on exact mirror scenes, ambiguous scenes, continuity, and the plugin."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.core import Session
from mirrorlab.plugins.pairing import (
    InvalidPairingInput,
    epipolar_distance,
    mirror_epipole,
    mirror_of_points,
    ordering_ok,
    pair_mirror,
    undistort_points,
)
from mirrorlab.plugins.photogrammetry import PinholeCamera, reflect

from tests.tolerances import roundoff

from .scene import CAMERA, MIRRORS, P, epipoles, images, markers


def distance_roundoff(real: np.ndarray, virtual: np.ndarray, e: np.ndarray) -> float:
    """Rounding bound (px) of epipolar_distance for exact images.

    The triple product (p x e) . q (homogeneous p, q) vanishes by cancellation: its rounding is ~eps
    times the componentwise magnitude |p x e| . |q| (|a x b| with every product taken in absolute
    value), divided by the line's |(p x e)_xy|; the images carry ~10 roundings of their pixel
    coordinates from the projection.
    """
    ph, qh = np.c_[real, np.ones(len(real))], np.c_[virtual, np.ones(len(virtual))]
    a, b = np.abs(ph), np.abs(e)
    abs_cross = np.stack([a[:, 1] * b[2] + a[:, 2] * b[1], a[:, 2] * b[0] + a[:, 0] * b[2],
                          a[:, 0] * b[1] + a[:, 1] * b[0]], axis=1)
    terms = abs_cross @ np.abs(qh).T  # (N, M), every combination
    lp, lq = np.cross(ph, e), np.cross(qh, e)
    scale = terms / np.hypot(lp[:, 0], lp[:, 1])[:, None] + terms / np.hypot(lq[:, 0], lq[:, 1])[None, :]
    return roundoff(scale=float(0.5 * scale.max() + np.abs(np.r_[real, virtual]).max()), ops=10)


def _shuffled(rng, real, virtual):
    """Stack the mirror images of all mirrors in random order; truth[j] = (real index, mirror)."""
    stacked = np.concatenate(virtual)
    truth = np.array([(i, k) for k in range(len(virtual)) for i in range(len(real))])
    perm = rng.permutation(len(stacked))
    return stacked[perm], truth[perm]


def _check_correct(res, truth):
    for r, v, k in res.pairs:
        assert (r, k) == tuple(truth[v]), f"virtual {v} paired with real {r} in mirror {k}, truth {truth[v]}"


def test_epipole_is_the_image_of_the_virtual_camera_and_lines_pass_through_it() -> None:
    rng = np.random.default_rng(0)
    pts = markers(rng, 30)
    real, virtual = images(pts)
    for k, (g, n) in enumerate(MIRRORS):
        e = mirror_epipole(P, CAMERA.camera_center, g, n)
        d = epipolar_distance(real, virtual[k], e)
        # exact scene: zero distance, to rounding
        np.testing.assert_allclose(np.diag(d), 0.0, atol=distance_roundoff(real, virtual[k], e))
        assert np.all(np.diag(ordering_ok(real, virtual[k], e)))
    assert epipoles()[0, 2] > 0 and epipoles()[2, 2] < 0  # in front of / behind the camera


@pytest.mark.parametrize("noise", [0.0, 0.3])
@pytest.mark.parametrize("n_mirrors", [1, 3])
def test_generated_mirror_scene_is_paired_completely_and_correctly(noise: float, n_mirrors: int) -> None:
    """12 markers, 1 or 3 mirrors (mirror images shuffled, mirror labels known): 100 % paired, 0 wrong."""
    rng = np.random.default_rng(2)
    mirrors = MIRRORS[:n_mirrors]
    pts = markers(rng, 12, mirrors)
    real, virtual = images(pts, mirrors)
    real = real + rng.normal(0, noise, real.shape)
    virtual = [v + rng.normal(0, noise, v.shape) for v in virtual]
    stacked, truth = _shuffled(rng, real, virtual)
    res = pair_mirror(real, stacked, epipoles(mirrors), tol=2.0, virtual_mirror=truth[:, 1])
    _check_correct(res, truth)
    assert len(res.pairs) == len(stacked) and not res.ambiguous
    assert res.unpaired_virtual.size == 0 and res.unpaired_real.size == 0
    assert res.cost.max() <= 2.0  # pairs are accepted within tol (0.3 px noise: distances ~0.4 px)
    np.testing.assert_array_equal(res.virtual_index(len(real), n_mirrors)[truth[:, 0], truth[:, 1]],
                                  np.arange(len(stacked)))


@settings(max_examples=20, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 30), labelled=st.booleans())
def test_decided_pairs_are_never_wrong_and_ambiguity_is_justified(seed: int, n: int, labelled: bool) -> None:
    """Random 3-mirror scenes with 0.2 px noise and spurious blobs: no decided pair is wrong, every
    marker is paired or reported ambiguous, and each report names ≥ 2 candidates within tolerance."""
    rng = np.random.default_rng(seed)
    pts = markers(rng, n)
    real, virtual = images(pts)
    stacked, truth = _shuffled(rng, real + rng.normal(0, 0.2, real.shape),
                               [v + rng.normal(0, 0.2, v.shape) for v in virtual])
    stacked = np.concatenate([stacked, rng.uniform([0, 0], [1280, 960], (3, 2))])
    truth = np.concatenate([truth, [(-1, -1)] * 3])
    labels = truth[:, 1] if labelled else None
    e = epipoles()
    res = pair_mirror(real, stacked, e, tol=1.5, virtual_mirror=labels)
    _check_correct(res, truth)
    assert len(res.pairs) + len(res.ambiguous) >= 3 * n - 2 * len(res.ambiguous)
    for amb in res.ambiguous:
        assert len(amb.candidates) >= 2
        d = epipolar_distance(real[amb.real:amb.real + 1], stacked[list(amb.candidates)], e[amb.mirror])
        assert np.all(d <= 1.5)  # every candidate named is within the tol given to pair_mirror


def test_continuity_over_a_sequence_decides_what_single_frames_cannot() -> None:
    rng = np.random.default_rng(4)
    pts = markers(rng, 25, MIRRORS[:1])
    vel = rng.normal(0, 3.0, pts.shape)  # mm per frame
    e = epipoles(MIRRORS[:1])
    previous, undecided_alone, undecided_seq = None, 0, 0
    for f in range(30):
        real, virtual = images(pts + f * vel, MIRRORS[:1])
        real, v = real + rng.normal(0, 0.1, real.shape), virtual[0] + rng.normal(0, 0.1, real.shape)
        perm = rng.permutation(len(v))
        alone = pair_mirror(real, v[perm], e, tol=1.0)
        seq = pair_mirror(real, v[perm], e, tol=1.0, previous=previous)
        for res in (alone, seq):
            assert np.array_equal(perm[res.pairs[:, 1]], res.pairs[:, 0])  # never wrong
        undecided_alone += len(alone.ambiguous)
        undecided_seq += len(seq.ambiguous) if f else 0
        previous = (real[seq.pairs[:, 0]], v[perm][seq.pairs[:, 1]], seq.pairs[:, 2])
    assert undecided_alone > 0 and undecided_seq < undecided_alone / 2


def _ambiguous_scene():
    """Two markers A, B in one plane with the camera and the mirror normal: all four images on one line."""
    g, n = MIRRORS[0]
    a = np.array([100.0, 50.0, 1000.0])
    b = 1.3 * a + 150.0 * n  # farther along the camera ray of A, shifted along the normal
    pts = np.array([a, b])
    real, virtual = images(pts, [(g, n)])
    return pts, real, virtual[0], epipoles([(g, n)])


def test_two_markers_on_one_epipolar_line_are_reported_not_guessed() -> None:
    _, real, virtual, e = _ambiguous_scene()
    d = epipolar_distance(real, virtual, e[0])
    assert np.all(d <= distance_roundoff(real, virtual, e[0]))  # every combination is on the line (exact scene)
    assert ordering_ok(real, virtual, e[0]).all()  # and satisfies the ordering
    res = pair_mirror(real, virtual, e, tol=2.0)
    assert len(res.pairs) == 0
    assert sorted((a.real, a.mirror, a.candidates) for a in res.ambiguous) == [(0, 0, (0, 1)), (1, 0, (0, 1))]
    assert res.unpaired_real.tolist() == [0, 1] and res.unpaired_virtual.tolist() == [0, 1]


def test_continuity_resolves_the_ambiguous_scene() -> None:
    pts, real, virtual, e = _ambiguous_scene()
    g, n = MIRRORS[0]
    prev_pts = pts + [[3.0, 0.0, 0.0], [-3.0, 2.0, 0.0]]
    prev_real, prev_virtual = images(prev_pts, [(g, n)])
    res = pair_mirror(real, virtual[::-1], e, tol=2.0, previous=(prev_real, prev_virtual[0], np.zeros(2)))
    assert res.pairs.tolist() == [[0, 1, 0], [1, 0, 0]] and not res.ambiguous


def test_ordering_decides_when_only_one_assignment_fits() -> None:
    """Same line, but B's mirror image lies beyond A: (A, B') breaks the ordering, so nothing is ambiguous."""
    _, real, virtual, e = _ambiguous_scene()
    ok = ordering_ok(real, virtual, e[0])
    ei = e[0, :2] / e[0, 2]
    t = lambda p: np.linalg.norm(p - ei)  # noqa: E731
    far, near = (0, 1) if t(real[0]) > t(real[1]) else (1, 0)
    moved = virtual.copy()
    moved[far] = ei + (real[near] - ei) * 1.05  # A' just beyond B: only A can own it
    moved[near] = ei + (real[near] - ei) * 0.5
    ok = ordering_ok(real, moved, e[0])
    assert ok[far, far] and not ok[near, far]
    res = pair_mirror(real, moved, e, tol=2.0)
    assert sorted(res.pairs[:, :2].tolist()) == [[0, 0], [1, 1]] and not res.ambiguous


def test_virtual_mirror_labels_and_image_regions() -> None:
    rng = np.random.default_rng(3)
    pts = markers(rng, 10)
    real, virtual = images(pts)
    stacked, truth = _shuffled(rng, real, virtual)
    res = pair_mirror(real, stacked, epipoles(), virtual_mirror=truth[:, 1])
    _check_correct(res, truth)
    wrong = pair_mirror(real, stacked, epipoles(), virtual_mirror=(truth[:, 1] + 1) % 3)
    assert len(wrong.pairs) < len(stacked) // 3  # wrong labels: hardly anything fits
    square = [[0, 0], [100, 0], [100, 100], [0, 100]]
    assert mirror_of_points([[50, 50], [150, 50], [99, 1]], [square, [[100, 0], [200, 0], [200, 100]]]).tolist() \
        == [0, 1, 0]


def test_distorted_images_are_undistorted_before_pairing() -> None:
    dist = np.array([-0.25, 0.08, 0.0, 0.0, 0.0])
    cam = PinholeCamera(CAMERA.K, dist, np.eye(3), np.zeros(3))
    rng = np.random.default_rng(5)
    pts = markers(rng, 12, MIRRORS[:1])
    g, n = MIRRORS[0]
    real, virtual = cam.project(pts), cam.project(reflect(pts, g, n))
    e = epipoles(MIRRORS[:1])
    raw = epipolar_distance(real, virtual, e[0])
    assert np.diag(raw).max() > 2.0  # distortion bends the epipolar lines
    res = pair_mirror(undistort_points(real, cam.K, dist), undistort_points(virtual, cam.K, dist), e)
    assert res.pairs[:, :2].tolist() == [[i, i] for i in range(12)]


@pytest.mark.parametrize("kwargs, match", [
    ({"real_xy": np.zeros((2, 3))}, "real_xy must have shape"),
    ({"virtual_xy": [[np.nan, 1.0]]}, "not finite"),
    ({"epipoles": np.zeros((1, 3))}, "epipole is"),
    ({"epipoles": np.zeros((1, 4))}, "epipoles must be"),
    ({"tol": 0.0}, "tol and motion_gate"),
    ({"virtual_mirror": [3]}, "virtual_mirror"),
])
def test_bad_input_raises(kwargs, match) -> None:
    args = dict(real_xy=[[0.0, 0.0]], virtual_xy=[[5.0, 0.0]], epipoles=[[10.0, 0.0, 1.0]])
    args.update(kwargs)
    with pytest.raises(InvalidPairingInput, match=match):
        pair_mirror(args.pop("real_xy"), args.pop("virtual_xy"), args.pop("epipoles"), **args)


def test_pair_mirror_plugin_over_frames(tmp_path: Path) -> None:
    """Frames of a moving marker set (with the ambiguous configuration in the last frame)."""
    rng = np.random.default_rng(8)
    base = markers(rng, 6, MIRRORS[:1])
    g, n = MIRRORS[0]
    frames_real, frames_virtual, truth = [], [], []
    for f in range(4):
        pts = base + [2.0 * f, 0.0, 0.0]
        real, virtual = images(pts, [(g, n)])
        perm = rng.permutation(6)
        frames_real.append(real)
        frames_virtual.append(np.concatenate([virtual[0][perm], [[np.nan, np.nan]]]))
        truth.append(np.argsort(perm))
    path = tmp_path / "pair.h5"
    with Session.create(path) as s:
        s.write_group("truth/pairs", {"real": np.array(frames_real), "virtual": np.array(frames_virtual),
                                      "epipoles": epipoles(MIRRORS[:1])})
        ref = s.run("pair_mirror", {k: f"/truth/pairs/{k}" for k in ("real", "virtual", "epipoles")})
        assert ref.status == "ok", ref.error
        out = s.result(ref).outputs
    np.testing.assert_array_equal(out["virtual_index"][:, :, 0], np.array(truth))
    assert out["n_ambiguous"].tolist() == [0, 0, 0, 0]
    # the plugin copies the input coordinates: exact
    np.testing.assert_array_equal(out["virtual_xy"][1, 2, 0], np.array(frames_virtual)[1, truth[1][2]])
