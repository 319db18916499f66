"""Tracking: crossings, gaps, spurious detections, id stability, permutation invariance, plugin."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.core import Session
from mirrorlab.core.algorithms import execute
from mirrorlab.plugins.tracking import InvalidDetections, track
from mirrorlab.plugins.tracking.algorithms import Track

from tests.tolerances import roundoff


def _circles(n_frames: int, n: int, seed: int = 0) -> np.ndarray:
    """(F, n, 2) smooth, well separated trajectories (circles on a grid), px."""
    rng = np.random.default_rng(seed)
    t = np.arange(n_frames)[:, None]
    grid = np.stack(np.meshgrid(np.arange(n) % 10, np.arange(n) // 10), -1).reshape(-1, 2)[:n]
    c = 100.0 + 120.0 * grid + rng.uniform(-5, 5, (n, 2))
    r, w, ph = rng.uniform(10, 30, n), rng.uniform(0.02, 0.08, n), rng.uniform(0, 2 * np.pi, n)
    return np.stack([c[:, 0] + r * np.cos(w * t + ph), c[:, 1] + r * np.sin(w * t + ph)], -1)


def _frames(truth: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
    """Per-frame detections in random order, NaN rows (missing) removed."""
    out = []
    for xy in truth:
        xy = xy[np.all(np.isfinite(xy), axis=1)]
        out.append(xy[rng.permutation(len(xy))])
    return out


def _assert_tracks_equal_truth(tracks, truth: np.ndarray) -> None:
    """Each true marker is exactly one track (same NaN pattern, same positions)."""
    assert tracks.n_tracks == truth.shape[1]
    first = np.array([truth[np.argmax(np.isfinite(truth[:, i, 0])), i] for i in range(truth.shape[1])])
    for i in range(truth.shape[1]):
        hits = [t for t in range(tracks.n_tracks)
                if np.allclose(tracks.xy[tracks.first[t], t], first[i]) and tracks.first[t] ==
                np.argmax(np.isfinite(truth[:, i, 0]))]
        assert len(hits) == 1
        np.testing.assert_array_equal(tracks.xy[:, hits[0]], truth[:, i])


def test_crossing_trajectories_keep_their_ids_with_prediction_but_not_with_nearest() -> None:
    t = np.arange(40.0)
    a = np.c_[10 + 5 * t, 100 + 2 * t]  # the two paths cross near frame 20
    b = np.c_[10 + 5 * t, 180 - 2 * t]
    truth = np.stack([a, b], axis=1)
    frames = _frames(truth, np.random.default_rng(0))
    tr = track(frames, gate=5.0)
    _assert_tracks_equal_truth(tr, truth)
    # constant velocity: perfect prediction, to the rounding of 2 x1 - x0 at coordinates <= 205 px
    # (exact here: integer coordinates)
    np.testing.assert_allclose(tr.residual, 0.0, atol=roundoff(scale=205.0, ops=4))
    np.testing.assert_array_equal(tr.present, 1.0)
    near = track(frames, "nearest", gate=np.inf)
    assert near.n_tracks == 2
    assert not (np.array_equal(near.xy[:, 0], a) and np.array_equal(near.xy[:, 1], b))  # the thesis rule fails


def test_nearest_is_exact_on_well_separated_motion_and_follows_the_listing() -> None:
    truth = _circles(60, 12, seed=1)
    rng = np.random.default_rng(1)
    frames = _frames(truth, rng)
    near = track(frames, "nearest", gate=np.inf)
    order = np.lexsort((truth[0, :, 0], truth[0, :, 1]))  # labels in raster order of frame 0
    np.testing.assert_array_equal(near.xy, truth[:, order])
    # no exclusivity: two tracks can take the same detection; a tie goes to the later detection
    two = track([np.array([[0.0, 0.0], [10.0, 0.0]]), np.array([[5.0, 0.0], [5.0, 0.0], [100.0, 0.0]])],
                "nearest", gate=np.inf)
    assert two.index[1].tolist() == [1, 1]


def test_gaps_up_to_max_gap_keep_the_id_longer_gaps_start_a_new_track() -> None:
    truth = _circles(50, 6, seed=2)
    truth[10:13, 0] = np.nan  # 3 missing frames
    truth[30:37, 1] = np.nan  # 7 missing frames
    frames = _frames(truth, np.random.default_rng(2))
    tr = track(frames, gate=3.0, max_gap=5)
    assert tr.n_tracks == 7  # marker 1 split into two tracks, marker 0 kept
    spans = sorted(zip(tr.first.tolist(), tr.last.tolist(), strict=False))
    assert spans == [(0, 29)] + [(0, 49)] * 5 + [(37, 49)]
    t0 = next(t for t in range(tr.n_tracks) if np.allclose(tr.xy[0, t], truth[0, 0]))
    np.testing.assert_array_equal(tr.xy[:, t0], truth[:, 0])
    assert tr.present[t0] == pytest.approx(47 / 50)
    assert track(frames, gate=3.0, max_gap=7).n_tracks == 6


def test_spurious_detections_do_not_disturb_tracks_and_min_length_removes_them() -> None:
    rng = np.random.default_rng(3)
    truth = _circles(80, 20, seed=3)
    frames = []
    for f, xy in enumerate(_frames(truth, rng)):
        junk = rng.uniform([0, 0], [1300, 400], (rng.integers(0, 4), 2))
        junk = junk[np.min(np.linalg.norm(junk[:, None] - truth[f][None], axis=2), axis=1) > 15] \
            if len(junk) else junk
        frames.append(rng.permutation(np.concatenate([xy, junk])))
    tr = track(frames, gate=3.0, max_gap=0, min_length=3)
    _assert_tracks_equal_truth(tr, truth)
    assert track(frames, gate=3.0, max_gap=0).n_tracks > 20


@settings(max_examples=15, deadline=None)
@given(seed=st.integers(0, 10_000), method=st.sampled_from(["predictive", "nearest"]))
def test_permuting_detections_within_frames_does_not_change_tracks(seed: int, method: str) -> None:
    rng = np.random.default_rng(seed)
    truth = _circles(30, 8, seed=seed)
    truth[rng.random(truth.shape[:2]) < 0.1] = np.nan
    frames = _frames(truth, rng)
    a = track(frames, method, gate=5.0)
    b = track([f[rng.permutation(len(f))] for f in frames], method, gate=5.0)
    np.testing.assert_array_equal(a.xy, b.xy)
    np.testing.assert_array_equal(a.present, b.present)


def test_quality_figures() -> None:
    t = np.arange(10.0)
    truth = np.c_[5 * t, 0 * t][:, None, :].copy()
    truth[4, 0] = np.nan
    truth[7, 0] += [0.5, 0.0]  # one detection off by 0.5 px
    tr = track(_frames(truth, np.random.default_rng(0)), gate=2.0, initial_gate=6.0)
    assert tr.n_tracks == 1 and tr.present[0] == pytest.approx(0.9)  # 9 of 10 frames
    # residuals: frames 2, 3, 5, 6 exact (5 bridges the gap), 7 off 0.5, 8 off 1.0 (velocity from 7), 9 off 0.5;
    # half-integer coordinates: exact but for the mean's division
    assert tr.residual[0] == pytest.approx((0.5 + 1.0 + 0.5) / 7, abs=roundoff(scale=1.0, ops=8))


@pytest.mark.parametrize("kwargs, match", [
    ({"method": "kalman"}, "unknown tracking method"),
    ({"gate": 0.0}, "gate"),
    ({"max_gap": -1}, "max_gap"),
])
def test_bad_options(kwargs, match) -> None:
    with pytest.raises(InvalidDetections, match=match):
        track([np.zeros((1, 2))], **kwargs)


def test_bad_frame_is_named() -> None:
    with pytest.raises(InvalidDetections, match="frame 1"):
        track([np.zeros((1, 2)), np.zeros((1, 3))])
    with pytest.raises(InvalidDetections, match="frame 0: a detection has one NaN"):
        track([np.array([[np.nan, 1.0]])])


def test_track_plugin_with_padding_and_counts(tmp_path: Path) -> None:
    truth = _circles(20, 5, seed=5)
    padded = np.full((20, 7, 2), np.nan)
    padded[:, :5] = truth[:, ::-1]
    padded[:, 5] = 9999.0  # beyond counts: ignored
    counts = np.full(20, 5)
    out = execute(Track, {"detections": padded, "counts": counts}, {"gate": "3"})
    assert out.status == "ok", out.error
    assert out.outputs["xy"].shape == (20, 5, 2)
    path = tmp_path / "t.h5"
    with Session.create(path) as s:
        s.write_group("truth/det", {"xy": padded, "counts": counts})
        ref = s.run("track", {"detections": "/truth/det/xy", "counts": "/truth/det/counts"}, {"method": "nearest"})
        assert ref.status == "ok", ref.error
        res = s.result(ref).outputs
    order = np.lexsort((truth[0, :, 0], truth[0, :, 1]))
    np.testing.assert_array_equal(res["xy"], truth[:, order])
    bad = execute(Track, {"detections": np.zeros((3, 4))}, {})
    assert bad.status == "failed" and "InvalidDetections" in bad.error
