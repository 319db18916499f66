"""Rigid grouping from unlabeled, shuffled tracks with gaps, in 2-D and 3-D (analysis.md §3)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.plugins.mechanisms import GroupingError, InvalidPoints, rigid_groups, thesis_groups
from mirrorlab.plugins.mechanisms.fourbar import track_markers
from mirrorlab.plugins.mechanisms.synthetic import four_bar_markers
from scipy.spatial.transform import Rotation

from tests.tolerances import roundoff


def _true_labels(tracks: np.ndarray, truth: np.ndarray) -> list[int]:
    """Scene label of each track (the nearest true marker in every frame must agree)."""
    labels = []
    for j in range(tracks.shape[1]):
        d = np.linalg.norm(tracks[:, j, None] - truth, axis=-1)
        near = np.nanargmin(np.where(np.isfinite(d), d, np.inf), axis=1)[np.isfinite(tracks[:, j, 0])]
        assert len(set(near.tolist())) == 1, f"track {j} switches markers: {near}"
        labels.append(int(near[0]))
    return labels


SCENE_GROUPS = {(0, 1, 2), (3, 4), (5, 6), (7, 8)}          # frame, crank, coupler, rocker of FourBarScene


@pytest.mark.parametrize("noise,missing", [("none", 0.0), ("none", 0.1), ("uniform", 0.0), ("uniform", 0.1),
                                           ("gaussian", 0.0)])
def test_four_bar_groups_from_shuffled_tracks(noise: str, missing: float) -> None:
    points, truth = four_bar_markers(30, noise=noise, missing=missing, seed=3)
    tracks = track_markers(points)
    labels = _true_labels(tracks, truth)
    g = rigid_groups(tracks)
    assert g.ground == 0
    found = {tuple(sorted(labels[i] for i in grp)) for grp in (g.groups[0], *g.select(3))}
    assert found == SCENE_GROUPS
    assert np.all(g.stationary[[labels.index(k) for k in (0, 1, 2)]])


def _bodies_3d(T: int = 40, seed: int = 0) -> tuple[np.ndarray, list[tuple[int, ...]]]:
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 2, T)
    bodies = []
    for b in range(3):
        local = rng.uniform(-60, 60, (3 + b, 3))
        axis = rng.normal(size=3)
        R = Rotation.from_rotvec(np.outer((1.0 + b) * t, axis / np.linalg.norm(axis))).as_matrix()   # (T, 3, 3)
        centre = np.stack([100 * b + 30 * np.sin(t * (b + 1)), 20 * t, 5 * b + 0 * t], -1)
        bodies.append(np.einsum("tij,mj->tmi", R, local) + centre[:, None])
    fixed = np.broadcast_to(rng.uniform(-200, 200, (3, 3)), (T, 3, 3))
    pts = np.concatenate([fixed, *bodies], 1)
    groups = [(0, 1, 2), (3, 4, 5), (6, 7, 8, 9), (10, 11, 12, 13, 14)]
    return pts, groups


def test_3d_groups_with_gaps_and_permuted_columns() -> None:
    pts, groups = _bodies_3d()
    pts = pts.copy()
    pts[5:9, 4] = np.nan
    pts[20:22, 11] = np.nan
    perm = np.random.default_rng(1).permutation(pts.shape[1])
    g = rigid_groups(pts[:, perm])
    back = {tuple(sorted(int(perm[i]) for i in grp)) for grp in g.groups}
    assert back == set(groups)
    assert g.ground is not None and tuple(sorted(perm[list(g.groups[g.ground])])) == (0, 1, 2)
    # noiseless: the estimated tolerance is 4x the distances' rounding noise, floored at 1e-9 of the
    # coordinate scale (estimate_tolerance)
    scale = float(np.nanmax(np.abs(pts)))
    assert g.tol <= max(4 * roundoff(scale=scale, ops=10), 1e-9 * scale)


def test_3d_groups_with_noise() -> None:
    pts, groups = _bodies_3d(60, seed=2)
    noisy = pts + np.random.default_rng(4).normal(scale=0.3, size=pts.shape)
    g = rigid_groups(noisy)
    assert set(g.groups) == set(groups)
    # 0.3 mm per coordinate makes a distance's step noise sqrt(2) · 0.3 = 0.42 mm; the tolerance is
    # 4x the smallest estimate over the rigid pairs (~1.4 mm); a wide statistical bracket around it
    assert 0.3 < g.tol < 5.0



@settings(max_examples=25, deadline=None)
@given(st.permutations(list(range(15))), st.integers(0, 3))
def test_grouping_invariant_under_marker_shuffling(perm: list[int], seed: int) -> None:
    pts, _ = _bodies_3d(30, seed)
    a = rigid_groups(pts)
    b = rigid_groups(pts[:, perm])
    mapped = {tuple(sorted(perm[i] for i in grp)) for grp in b.groups}
    assert mapped == set(a.groups)


def test_thesis_grouping_on_the_four_bar() -> None:
    points, truth = four_bar_markers(30, noise="uniform", seed=5)
    tracks = track_markers(points)
    labels = _true_labels(tracks, truth)
    fixed, pairs = thesis_groups(tracks)
    assert sorted(labels[i] for i in fixed) == [0, 1, 2]
    assert {tuple(sorted((labels[i], labels[j]))) for i, j in pairs} == {(3, 4), (5, 6), (7, 8)}


def test_nearest_neighbour_tracking_breaks_on_close_markers() -> None:
    """The thesis's tracking rule needs steps < half the marker spacing; this scene violates it (§2)."""
    points, truth = four_bar_markers(30, noise="uniform", seed=5)
    with pytest.raises(AssertionError, match="switches markers"):
        _true_labels(track_markers(points, "nearest"), truth)


def test_errors_name_the_problem() -> None:
    with pytest.raises(InvalidPoints, match=r"\(T, M, 2\) or \(T, M, 3\)"):
        rigid_groups(np.zeros((4, 3)))
    with pytest.raises(GroupingError, match="3 consecutive frames"):
        rigid_groups(np.full((5, 3, 2), np.nan))
    with pytest.raises(GroupingError, match="needs 3 fixed markers and 3 pairs"):
        thesis_groups(np.zeros((5, 4, 2)))
    pts, _ = _bodies_3d()
    with pytest.raises(GroupingError, match="expected 4 separate moving bodies"):
        rigid_groups(pts).select(4, min_size=3)
