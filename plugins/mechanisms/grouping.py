"""Rigid-body grouping of marker tracks (``analysis.md`` §3).

Which markers share a rigid body is read from the tracks alone: the distance between two markers
on one body is constant up to the measurement noise. Tracks are ``(T, M, D)`` arrays (frames,
markers, 2 or 3 coordinates, mm) with NaN where a marker is missing; the markers must already be
tracked (the same column is the same marker in every frame), see
:func:`mirrorlab.plugins.tracking.track`.

* :func:`rigid_groups` — the general method: an edge ``(i, j)`` is rigid when the standard deviation
  of the distance over the frames both markers are seen is below ``tol`` (mm; estimated from the
  noise when not given); bodies are the maximal cliques of rigid edges (>= 2 markers in 2-D, >= 3
  in 3-D); a body whose markers do not move is the ground.
* :func:`thesis_groups` — the thesis's Steps 1-3: the three markers with the smallest path length
  are fixed, then the pairs with the smallest summed distance change ``DS`` are taken greedily.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import networkx as nx
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import GroupingError, InvalidPoints

__all__ = ["RigidGroups", "as_tracks", "distance_spread", "estimate_tolerance", "path_lengths", "rigid_groups",
           "thesis_groups"]

FloatArray = NDArray[np.float64]

#: A rigid edge needs its distance measured in at least this many frames.
MIN_COMMON_FRAMES = 3


def as_tracks(points: ArrayLike, name: str = "points", dims: tuple[int, ...] = (2, 3)) -> FloatArray:
    """``points`` as a float ``(T, M, D)`` array; raises :class:`InvalidPoints` naming ``name``.

    Examples
    --------
    >>> as_tracks([[[0, 0], [1, 0]]]).shape
    (1, 2, 2)
    """
    p = np.asarray(points, dtype=float)
    if p.ndim != 3 or p.shape[2] not in dims:
        want = " or ".join(f"(T, M, {d})" for d in dims)
        raise InvalidPoints(f"{name} must be marker positions of shape {want} (frames, markers, coordinates, mm), "
                            f"got {p.shape}")
    return p


def _distances(tracks: FloatArray) -> FloatArray:
    return np.linalg.norm(tracks[:, :, None, :] - tracks[:, None, :, :], axis=-1)      # (T, M, M), NaN if missing


def distance_spread(tracks: ArrayLike) -> tuple[FloatArray, FloatArray, NDArray[np.int64]]:
    """Mean and standard deviation of every inter-marker distance over the frames it is seen.

    Parameters
    ----------
    tracks : (T, M, D) marker positions, mm, NaN where missing.

    Returns
    -------
    mean, std : (M, M) mm (NaN where fewer than 3 common frames).
    count : (M, M) number of frames both markers are seen.

    Examples
    --------
    >>> p = np.array([[[0, 0], [3, 4]], [[1, 0], [4, 4]], [[1, 1], [4, 5]]], float)
    >>> float(distance_spread(p)[1][0, 1])
    0.0
    """
    d = _distances(as_tracks(tracks, "tracks"))
    ok = np.isfinite(d)
    count = ok.sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(ok, d, 0.0).sum(0) / count
        std = np.sqrt(np.where(ok, (d - mean) ** 2, 0.0).sum(0) / count)
    few = count < MIN_COMMON_FRAMES
    mean[few], std[few] = np.nan, np.nan
    return mean, std, count


def _step_noise(d: FloatArray) -> tuple[FloatArray, NDArray[np.int64]]:
    """``sqrt(mean(diff(d)^2) / 2)`` per pair over consecutive frames (the noise of a constant d)."""
    dd = np.diff(d, axis=0)
    ok = np.isfinite(dd)
    n = ok.sum(0)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.sqrt(np.where(ok, dd**2, 0.0).sum(0) / n / 2.0), n


def estimate_tolerance(tracks: ArrayLike, factor: float = 4.0) -> float:
    """Rigidity tolerance (mm) from the noise of the inter-marker distances.

    The frame-to-frame change of a rigid distance is pure noise (standard deviation ``sqrt(2) s``
    for a distance noise ``s``), that of any other distance is noise plus motion, so the smallest
    ``std(diff(d)) / sqrt(2)`` over all pairs estimates ``s``; the tolerance is ``factor * s``, with
    a floor of 1e-9 of the distance scale for noiseless data.

    Parameters
    ----------
    tracks : (T, M, D) time-ordered marker positions, mm.
    factor : multiple of the estimated distance noise.

    Returns
    -------
    float
        Tolerance on the standard deviation of a rigid distance, mm.

    Raises
    ------
    GroupingError
        No pair of markers is seen in 3 consecutive frames.
    """
    p = as_tracks(tracks, "tracks")
    s, n = _step_noise(_distances(p))
    iu = np.triu_indices(p.shape[1], 1)
    s, n = s[iu], n[iu]
    s = s[(n >= MIN_COMMON_FRAMES - 1) & np.isfinite(s)]
    if s.size == 0:
        raise GroupingError("no pair of markers is seen in 3 consecutive frames, so the noise (and the rigidity "
                            "tolerance) cannot be estimated; give tol (mm) explicitly")
    scale = float(np.nanmax(np.abs(p))) if np.isfinite(p).any() else 1.0
    return max(factor * float(s.min()), 1e-9 * scale)


def path_lengths(tracks: ArrayLike) -> FloatArray:
    """Total path length ``sum_k |p_{k+1} - p_k|`` of each marker (mm; steps across gaps skipped).

    Examples
    --------
    >>> path_lengths(np.array([[[0, 0]], [[3, 4]], [[3, 5]]], float)).tolist()
    [6.0]
    """
    p = as_tracks(tracks, "tracks")
    step = np.linalg.norm(np.diff(p, axis=0), axis=-1)
    return np.where(np.isfinite(step), step, 0.0).sum(0)


@dataclass(frozen=True)
class RigidGroups:
    """Rigid bodies found among M markers.

    Attributes
    ----------
    groups : marker indices of each body (maximal cliques of rigid edges; ground first when there
        is one), sorted within a body. Bodies may share a marker (a marker on a joint) and, with
        noisy data, a spurious edge can create an extra overlapping group: :meth:`select` picks
        disjoint bodies.
    ground : index into ``groups`` of the stationary body, or ``None``.
    stationary : (M,) bool, markers whose position scatter is below ``tol``.
    tol : tolerance used, mm (standard deviation of a rigid distance / of a fixed position).
    std : (M, M) standard deviation of each inter-marker distance, mm.
    smoothness : (M, M) ``std / (rms frame-to-frame change / sqrt 2)``: about 1 for a distance that
        only carries noise, large for one that changes smoothly with the motion.
    unassigned : markers in no body.
    """

    groups: tuple[tuple[int, ...], ...]
    ground: int | None
    stationary: NDArray[np.bool_]
    tol: float
    std: FloatArray
    smoothness: FloatArray
    unassigned: tuple[int, ...]

    @property
    def moving(self) -> tuple[tuple[int, ...], ...]:
        """The bodies other than the ground."""
        return tuple(g for k, g in enumerate(self.groups) if k != self.ground)

    def score(self, group: tuple[int, ...]) -> float:
        """Largest smoothness ratio among the group's distances (lower = more clearly rigid)."""
        return max(float(self.smoothness[i, j]) for a, i in enumerate(group) for j in group[a + 1:])

    def select(self, count: int, min_size: int = 2) -> tuple[tuple[int, ...], ...]:
        """``count`` disjoint moving bodies covering the most markers, the most clearly rigid first.

        Candidates are the moving groups without their stationary markers, and their subsets of at
        least ``min_size`` markers; among the disjoint choices covering the most markers, the one
        with the smallest summed :meth:`score` wins.

        Raises
        ------
        GroupingError
            Fewer than ``count`` disjoint bodies exist.
        """
        free = [tuple(i for i in g if not self.stationary[i]) for g in self.moving]
        cands = sorted({sub for g in free for k in range(min_size, len(g) + 1) for sub in itertools.combinations(g, k)})
        best: tuple[int, float, tuple[tuple[int, ...], ...]] | None = None
        for combo in itertools.combinations(cands, count):
            members = [i for g in combo for i in g]
            if len(set(members)) != len(members):
                continue
            key = (-len(members), sum(self.score(g) for g in combo))
            if best is None or key < best[:2]:
                best = (*key, combo)
        if best is None:
            raise GroupingError(f"expected {count} separate moving bodies, found rigid groups {list(self.moving)} "
                                f"besides the ground (tolerance {self.tol:.3g} mm); pass tol (mm) if the noise "
                                "estimate is off, or check the tracks")
        return tuple(sorted(best[2]))


def rigid_groups(tracks: ArrayLike, tol: float | None = None, min_size: int | None = None,
                 factor: float = 4.0, smoothness: float | None = 2.0) -> RigidGroups:
    """Find the rigid bodies among tracked markers (maximal cliques of constant distances).

    Parameters
    ----------
    tracks : (T, M, 2) or (T, M, 3) tracked marker positions, mm, NaN where missing; time-ordered
        when ``tol`` is estimated or ``smoothness`` is used.
    tol : mm — largest standard deviation of a rigid distance and largest RMS scatter of a fixed
        marker about its mean; default :func:`estimate_tolerance` ``(tracks, factor)``.
    min_size : fewest markers of a body; default 2 in 2-D, 3 in 3-D (what fixes a pose).
    factor : noise multiple for the estimated tolerance.
    smoothness : a rigid distance must also have ``std <= smoothness * rms(diff) / sqrt(2)``: its
        variation looks like noise, not like a smooth change with the motion (separates distances
        that change by only a few noise levels; needs densely sampled, time-ordered frames;
        ``None`` switches the test off).

    Returns
    -------
    RigidGroups

    Raises
    ------
    InvalidPoints
        ``tracks`` is not (T, M, 2|3).
    GroupingError
        The tolerance cannot be estimated.

    Examples
    --------
    >>> t = np.linspace(0, 1, 8)[:, None]
    >>> body = np.stack([np.hstack([t, 0 * t]), np.hstack([t + 1, 0 * t])], 1)        # translating pair
    >>> still = np.stack([np.hstack([0 * t + 5, 0 * t]), np.hstack([0 * t + 5, 0 * t + 1])], 1)
    >>> other = np.hstack([np.cos(3 * t), np.sin(3 * t)])[:, None]
    >>> g = rigid_groups(np.concatenate([still, other, body], 1), tol=1e-6)
    >>> g.groups, g.ground, g.unassigned
    (((0, 1), (3, 4)), 0, (2,))
    """
    p = as_tracks(tracks, "tracks")
    M, D = p.shape[1], p.shape[2]
    tol = estimate_tolerance(p, factor) if tol is None else float(tol)
    if not tol > 0:
        raise GroupingError(f"tol must be a positive distance in mm, got {tol}")
    min_size = (2 if D == 2 else 3) if min_size is None else int(min_size)
    _, std, _ = distance_spread(p)
    noise, _ = _step_noise(_distances(p))
    floor = 1e-10 * (float(np.nanmax(np.abs(p))) if np.isfinite(p).any() else 1.0)    # round-off of a distance
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = std / np.maximum(noise, floor)
        centre = np.nanmean(p, axis=0)
        scatter = np.sqrt(np.nanmean(np.sum((p - centre) ** 2, axis=-1), axis=0))
        stationary = (np.isfinite(p).all(-1).sum(0) >= MIN_COMMON_FRAMES) & (scatter < tol)
        rigid = np.isfinite(std) & (std < tol)
        if smoothness is not None:
            rigid &= ~(ratio > smoothness)
    graph = nx.Graph()
    graph.add_nodes_from(range(M))
    graph.add_edges_from(zip(*np.nonzero(np.triu(rigid, 1))))
    cliques = sorted(tuple(sorted(int(i) for i in c)) for c in nx.find_cliques(graph) if len(c) >= min_size)
    ground_of = [k for k, c in enumerate(cliques) if all(stationary[list(c)])]
    ground = None
    if ground_of:
        best = max(ground_of, key=lambda k: len(cliques[k]))
        cliques.insert(0, cliques.pop(best))
        ground = 0
    used = {i for c in cliques for i in c}
    return RigidGroups(tuple(cliques), ground, stationary, tol, std, ratio, tuple(i for i in range(M) if i not in used))


def thesis_groups(tracks: ArrayLike, n_fixed: int = 3, n_pairs: int = 3) -> tuple[tuple[int, ...],
                                                                                   tuple[tuple[int, int], ...]]:
    """The thesis's grouping (Appendix 5 lines 1165-1545): fixed markers, then greedy pairs.

    Fixed markers are the ``n_fixed`` with the smallest total path length; among the rest, the pair
    with the smallest ``DS(i, j) = sum_k | |p_ki - p_kj| - |p_0i - p_0j| |`` is taken, its markers
    removed, and so on until ``n_pairs`` pairs are formed.

    Parameters
    ----------
    tracks : (T, M, D) tracked positions, mm; frame 0 must show every marker.
    n_fixed, n_pairs : the thesis has 3 frame markers and 3 moving links of two markers.

    Returns
    -------
    fixed : marker indices (sorted by path length).
    pairs : ``n_pairs`` index pairs, in the order they were taken.

    Raises
    ------
    GroupingError
        Fewer than ``n_fixed + 2 n_pairs`` markers, or a marker missing in frame 0.

    Examples
    --------
    >>> t = np.linspace(0, 1, 5)[:, None]
    >>> z = 0 * t
    >>> p = np.stack([np.hstack([z, z]), np.hstack([z + 9, z]), np.hstack([t, z + 1]), np.hstack([t, z + 2]),
    ...               np.hstack([2 * t, z + 5]), np.hstack([3 * t, z + 5])], 1)
    >>> thesis_groups(p, n_fixed=2, n_pairs=2)
    ((0, 1), ((2, 3), (4, 5)))
    """
    p = as_tracks(tracks, "tracks")
    M = p.shape[1]
    if M < n_fixed + 2 * n_pairs:
        raise GroupingError(f"the thesis grouping needs {n_fixed} fixed markers and {n_pairs} pairs "
                            f"({n_fixed + 2 * n_pairs} markers), the tracks have {M}")
    if not np.isfinite(p[0]).all():
        bad = int(np.flatnonzero(~np.isfinite(p[0]).all(-1))[0])
        raise GroupingError(f"the thesis grouping needs every marker in frame 0; marker {bad} is missing there "
                            "(use method='least_squares', which accepts gaps)")
    fixed = tuple(int(i) for i in np.argsort(path_lengths(p), kind="stable")[:n_fixed])
    d = _distances(p)
    ds = np.nansum(np.abs(d[1:] - d[0]), axis=0)
    free = [i for i in range(M) if i not in fixed]
    pairs: list[tuple[int, int]] = []
    while len(pairs) < n_pairs:
        i, j = min(((i, j) for a, i in enumerate(free) for j in free[a + 1:]), key=lambda e: ds[e])
        pairs.append((i, j))
        free = [k for k in free if k not in (i, j)]
    return fixed, tuple(pairs)
