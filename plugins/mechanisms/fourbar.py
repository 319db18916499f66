"""Planar four-bar reconstruction from unlabeled marker positions (``analysis.md`` §4).

:func:`reconstruct_four_bar` takes per-frame marker positions ``(T, M, 2)`` mm whose order may
change from frame to frame (NaN allowed), tracks them, finds the ground and the three moving links
from the constancy of distances, and estimates the linkage:

* ``method="least_squares"`` (default): frames registered on the fixed markers, circle fits over all
  frames (ground pivots = common centre of a side link's markers; the link whose markers' centres
  disagree most is the coupler), circle fits in the coupler frame for the moving joints, then a
  nonlinear least-squares fit of the four-bar model (pivots, lengths, crank angle per frame, marker
  offsets) to every marker position.
* ``method="thesis"``: the thesis's Steps 1-5 (Appendix 5): the three
  fixed markers with the shortest paths, greedy pairs of least distance change, poles of finite
  displacements (frames ``min_travel`` apart) for the ground pivots and the coupler, and the
  inversion about the coupler (circumcentres at frames N, N+10, N+20, N = 0..9) for the moving
  joints. Errors of Table 5.1's size appear at about 1 px of noise (§4.4).

Joint order everywhere: ``G1`` input ground pivot, ``J1`` input-coupler joint, ``J2``
coupler-output joint, ``G2`` output ground pivot. The input link is the side link that turns
through the larger angle.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from mirrorlab.plugins.tracking import track
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .errors import DegenerateGeometry, GroupingError, InvalidPoints
from .grouping import as_tracks, path_lengths, rigid_groups, thesis_groups
from .planar import apply_pose, circumcentre, common_centre, pole, pose2d, to_body

__all__ = ["FourBar", "LINK_NAMES", "reconstruct_four_bar", "track_markers"]

FloatArray = NDArray[np.float64]
Method = Literal["least_squares", "thesis"]
#: Keys of :attr:`FourBar.lengths`.
LINK_NAMES = ("ground", "input", "coupler", "output")


@dataclass(frozen=True)
class FourBar:
    """A reconstructed planar four-bar.

    Attributes
    ----------
    lengths : ``ground``, ``input``, ``coupler``, ``output`` link lengths (joint to joint), mm.
    ground_pivots : (2, 2) ``G1`` (input) and ``G2`` (output), mm.
    joints : (T, 4, 2) ``G1, J1, J2, G2`` per frame, mm.
    residuals : (T, M) distance of each moving marker from its position in the fitted linkage, mm
        (NaN for missing or fixed markers).
    rms : RMS of ``residuals``, mm.
    tracks : (T, M, 2) the tracked (and registered) marker positions the fit used, mm.
    links : marker indices (columns of ``tracks``) of ``ground``, ``input``, ``coupler``, ``output``.
    method : ``"least_squares"`` or ``"thesis"``.
    tol : rigidity tolerance used for grouping, mm (NaN for the thesis grouping).
    poles : thesis method only: ``input``, ``coupler``, ``output`` -> (3, 2) poles, mm.
    """

    lengths: dict[str, float]
    ground_pivots: FloatArray
    joints: FloatArray
    residuals: FloatArray
    rms: float
    tracks: FloatArray
    links: dict[str, tuple[int, ...]]
    method: str
    tol: float
    poles: dict[str, FloatArray] = field(default_factory=dict)

    def errors(self, truth: dict[str, float]) -> dict[str, float]:
        """Relative errors ``(found - true) / true`` per link for true lengths (mm)."""
        return {k: (self.lengths[k] - truth[k]) / truth[k] for k in LINK_NAMES if k in truth}


# ------------------------------------------------------------------------------------------------
# tracking
# ------------------------------------------------------------------------------------------------
def track_markers(points: ArrayLike, method: Literal["predictive", "nearest"] = "predictive",
                  gate: float | None = None) -> FloatArray:
    """Tracks ``(T, K, 2)`` from unordered per-frame positions ``(T, M, 2)`` (NaN rows = no marker).

    ``gate`` (mm) defaults to the smallest distance between two markers of one frame; tracks may
    bridge gaps of any length.

    Raises
    ------
    InvalidPoints
        Not (T, M, 2), fewer than 3 frames, or fewer than two markers in every frame.
    """
    p = as_tracks(points, "points", dims=(2,))
    if p.shape[0] < 3:
        raise InvalidPoints(f"points: a four-bar needs at least 3 frames, got {p.shape[0]}")
    if gate is None:
        d = np.linalg.norm(p[:, :, None] - p[:, None], axis=-1)
        d[:, np.arange(p.shape[1]), np.arange(p.shape[1])] = np.nan
        if not np.isfinite(d).any():
            raise InvalidPoints("points: no frame shows two markers; nothing to track")
        gate = float(np.nanmin(d))
    return track(p, method, gate=gate, max_gap=p.shape[0], min_length=3).xy


# ------------------------------------------------------------------------------------------------
# the four-bar model (shared by both methods, refined by the least-squares method)
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Layout:
    """How the parameter vector and the moving markers are laid out."""

    T: int
    counts: tuple[int, int, int]          # markers on input, coupler, output
    branch: float                          # +1 / -1: side of line J1-G2 on which J2 lies

    def offsets(self, x: FloatArray) -> list[FloatArray]:
        """Marker offsets (..., m, 2) in the input, coupler and output link frames."""
        out, start = [], 7 + self.T
        for m in self.counts:
            out.append(x[..., start:start + 2 * m].reshape(x.shape[:-1] + (m, 2)))
            start += 2 * m
        return out


def _joints(lay: _Layout, x: FloatArray) -> FloatArray:
    """Joints (..., T, 4, 2) = G1, J1, J2, G2 of parameter vectors ``x`` (..., n)."""
    G1, G2 = x[..., None, 0:2], x[..., None, 2:4]
    L1, L3, L4 = (x[..., k, None] for k in (4, 5, 6))
    theta = x[..., 7:7 + lay.T]
    J1 = G1 + L1[..., None] * np.stack([np.cos(theta), np.sin(theta)], -1)
    dv = G2 - J1
    dist = np.linalg.norm(dv, axis=-1)
    along = (L3**2 - L4**2 + dist**2) / (2 * dist)
    h = np.sqrt(np.maximum(L3**2 - along**2, 0.0))          # an unclosable trial pose is pulled to the limit
    ex = dv / dist[..., None]
    ey = np.stack([-ex[..., 1], ex[..., 0]], -1)
    J2 = J1 + along[..., None] * ex + lay.branch * h[..., None] * ey
    return np.stack([np.broadcast_to(G1, J1.shape), J1, J2, np.broadcast_to(G2, J1.shape)], -2)


def _frame(origin: FloatArray, tip: FloatArray) -> FloatArray:
    return np.arctan2(tip[..., 1] - origin[..., 1], tip[..., 0] - origin[..., 0])


def _predict(lay: _Layout, x: FloatArray) -> FloatArray:
    """Moving-marker positions (..., T, m_in + m_cp + m_out, 2) of parameter vectors ``x`` (..., n)."""
    J = _joints(lay, x)
    out = []
    for (o, t), q in zip(((0, 1), (1, 2), (3, 2)), lay.offsets(x)):
        ex = J[..., t, :] - J[..., o, :]
        ex = ex / np.linalg.norm(ex, axis=-1, keepdims=True)                    # (..., T, 2)
        ey = np.stack([-ex[..., 1], ex[..., 0]], -1)
        qx, qy = q[..., None, :, 0], q[..., None, :, 1]                          # (..., 1, m)
        out.append(J[..., o, None, :] + qx[..., None] * ex[..., None, :] + qy[..., None] * ey[..., None, :])
    return np.concatenate(out, -2)


def _initial(G1: FloatArray, G2: FloatArray, J1: FloatArray, J2: FloatArray,
             moving: FloatArray, counts: tuple[int, int, int]) -> tuple[_Layout, FloatArray]:
    """Parameter vector from pivots, per-frame joints (T, 2) and the moving markers (T, m, 2)."""
    T = J1.shape[0]
    cross = (G2[0] - J1[:, 0]) * (J2[:, 1] - J1[:, 1]) - (G2[1] - J1[:, 1]) * (J2[:, 0] - J1[:, 0])
    lay = _Layout(T, counts, 1.0 if np.nanmedian(cross) >= 0 else -1.0)
    theta = _frame(np.broadcast_to(G1, (T, 2)), J1)
    L1 = np.nanmean(np.linalg.norm(J1 - G1, axis=-1))
    L3 = np.nanmean(np.linalg.norm(J2 - J1, axis=-1))
    L4 = np.nanmean(np.linalg.norm(J2 - G2, axis=-1))
    offsets, start = [], 0
    for (o, t), m in zip(((np.broadcast_to(G1, (T, 2)), J1), (J1, J2), (np.broadcast_to(G2, (T, 2)), J2)), counts):
        local = to_body(_frame(o, t), o, moving[:, start:start + m])
        offsets.append(np.nanmean(local, axis=0).ravel())
        start += m
    x = np.concatenate([G1, G2, [L1, L3, L4], theta, *offsets])
    return lay, x


def _fit(lay: _Layout, x0: FloatArray, moving: FloatArray, refine: bool) -> tuple[FloatArray, FloatArray]:
    seen = np.isfinite(moving).all(-1)

    def resid(x: FloatArray) -> FloatArray:
        return (_predict(lay, x) - moving)[..., seen, :].reshape(x.shape[:-1] + (-1,))

    def jac(x: FloatArray) -> FloatArray:
        # forward differences, all parameters at once (one vectorised model call)
        h = 1e-7 * np.maximum(np.abs(x), 1.0)
        return ((resid(x + np.diag(h)) - resid(x)) / h[:, None]).T

    if not np.isfinite(x0).all():
        raise DegenerateGeometry("the initial linkage estimate is not finite (a link never seen in enough frames)")
    x = least_squares(resid, x0, jac=jac, method="lm", x_scale="jac").x if refine else x0
    return x, np.where(seen, np.linalg.norm(_predict(lay, x) - moving, axis=-1), np.nan)


# ------------------------------------------------------------------------------------------------
# least-squares method
# ------------------------------------------------------------------------------------------------
def _register(tracks: FloatArray, fixed: tuple[int, ...], reference_frame: int | None = None) -> FloatArray:
    """Map every frame onto the fixed markers' reference positions (removes film registration drift)."""
    ref = tracks[reference_frame, list(fixed)] if reference_frame is not None else np.nanmean(tracks[:, list(fixed)], 0)
    angle, shift = pose2d(ref, tracks[:, list(fixed)])
    bad = ~np.isfinite(angle)
    angle[bad], shift[bad] = 0.0, 0.0
    return to_body(angle, shift, tracks)


def _body_pose(points: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Pose (T,) of a rigid marker group (T, m, 2), reference = the Procrustes mean shape."""
    full = np.flatnonzero(np.isfinite(points).all((1, 2)))
    if full.size == 0:
        raise GroupingError("no frame shows all the markers of a link; cannot define its body frame")
    ref = points[full[0]]
    for _ in range(2):
        a, s = pose2d(ref, points)
        ref = np.nanmean(to_body(a, s, points), axis=0)
    return pose2d(ref, points)


def _rotation_range(points: FloatArray) -> float:
    a, _ = _body_pose(points)
    a = a[np.isfinite(a)]
    return float(np.ptp(np.unwrap(a))) if a.size else 0.0


def _centre_spread(points: FloatArray) -> float:
    """How far apart the circle centres of a link's markers are (large for the coupler), mm."""
    cs = []
    for j in range(points.shape[1]):
        try:
            cs.append(common_centre(points[:, j])[0])
        except DegenerateGeometry:
            return np.inf
    c = np.array(cs)
    return float(np.linalg.norm(c[:, None] - c[None], axis=-1).max())


def _least_squares(tracks: FloatArray, tol: float | None, register: bool, refine: bool) -> FourBar:
    groups = rigid_groups(tracks, tol=tol)
    if groups.ground is None and groups.groups:
        # film drift moves the frame markers too: the ground is the rigid group with the shortest paths
        k = int(np.argmin([path_lengths(tracks[:, list(g)]).mean() for g in groups.groups]))
        still = np.zeros_like(groups.stationary)
        still[list(groups.groups[k])] = True
        groups = replace(groups, ground=k, stationary=still)
    moving = groups.select(3)
    fixed = groups.groups[groups.ground] if groups.ground is not None else ()
    if register and len(fixed) >= 2:
        tracks = _register(tracks, fixed)
    spread = [_centre_spread(tracks[:, list(g)]) for g in moving]
    ic = int(np.argmax(spread))
    sides = [g for k, g in enumerate(moving) if k != ic]
    sides.sort(key=lambda g: -_rotation_range(tracks[:, list(g)]))
    inp, cpl, out = sides[0], moving[ic], sides[1]
    G1 = common_centre(tracks[:, list(inp)])[0]
    G2 = common_centre(tracks[:, list(out)])[0]
    ca, cs = _body_pose(tracks[:, list(cpl)])
    ok = np.isfinite(ca)
    J = []
    for side in (inp, out):
        local = to_body(ca[ok], cs[ok], tracks[ok][:, list(side)])
        J.append(common_centre(local)[0])
    Jw = apply_pose(np.nan_to_num(ca), np.nan_to_num(cs), np.broadcast_to(np.array(J), (len(ca), 2, 2)))
    Jw[~ok] = np.nan
    J1, J2 = _fill(Jw[:, 0], G1), _fill(Jw[:, 1], G2)
    return _result(tracks, groups.tol, fixed, inp, cpl, out, G1, G2, J1, J2, refine, "least_squares", {})


def _fill(J: FloatArray, G: FloatArray) -> FloatArray:
    """Joint positions for frames without a coupler pose: interpolate the angle about the pivot."""
    bad = ~np.isfinite(J).all(-1)
    if not bad.any():
        return J
    a = np.arctan2(J[:, 1] - G[1], J[:, 0] - G[0])
    k = np.flatnonzero(~bad)
    a = np.interp(np.arange(len(J)), k, np.unwrap(a[k]))
    r = np.nanmean(np.linalg.norm(J - G, axis=-1))
    return G + r * np.stack([np.cos(a), np.sin(a)], -1)


def _result(tracks: FloatArray, tol: float, fixed: tuple[int, ...], inp: tuple[int, ...], cpl: tuple[int, ...],
            out: tuple[int, ...], G1: FloatArray, G2: FloatArray, J1: FloatArray, J2: FloatArray, refine: bool,
            method: str, poles: dict[str, FloatArray]) -> FourBar:
    cols = list(inp) + list(cpl) + list(out)
    lay, x0 = _initial(G1, G2, J1, J2, tracks[:, cols], (len(inp), len(cpl), len(out)))
    x, res = _fit(lay, x0, tracks[:, cols], refine)
    joints = _joints(lay, x)
    G1, G2, L1, L3, L4 = x[0:2], x[2:4], *x[4:7]
    residuals = np.full(tracks.shape[:2], np.nan)
    residuals[:, cols] = res
    lengths = {"ground": float(np.linalg.norm(G2 - G1)), "input": float(L1), "coupler": float(L3),
               "output": float(L4)}
    if not refine:      # the estimates themselves, not the model's closure of them
        joints = np.stack([np.broadcast_to(G1, J1.shape), J1, J2, np.broadcast_to(G2, J2.shape)], 1)
    return FourBar(lengths, np.array([G1, G2]), joints, residuals, float(np.sqrt(np.nanmean(res**2))), tracks,
                   {"ground": tuple(fixed), "input": tuple(inp), "coupler": tuple(cpl), "output": tuple(out)},
                   method, tol, poles)


# ------------------------------------------------------------------------------------------------
# thesis method (Steps 1-5)
# ------------------------------------------------------------------------------------------------
def _thesis_frames(path: FloatArray, min_travel: float, count: int) -> list[int]:
    """Frames k_0 = 0 < k_1 < ... where the marker's path from frame 0 first exceeds J * min_travel."""
    step = np.linalg.norm(np.diff(path, axis=0), axis=-1)
    travelled = np.concatenate([[0.0], np.cumsum(step)])
    frames = [0]
    for J in range(1, count + 1):
        k = np.flatnonzero(travelled > J * min_travel)
        if k.size == 0:
            raise DegenerateGeometry(f"a marker travels only {travelled[-1]:.4g} mm in all, less than "
                                     f"{count} x min_travel = {count * min_travel:.4g} mm needed for {count} poles; "
                                     "lower min_travel or give more frames")
        frames.append(int(k[0]))
    return frames


def _thesis(tracks: FloatArray, min_travel: float, inversion_step: int, inversion_starts: int) -> FourBar:
    T = tracks.shape[0]
    if inversion_starts - 1 + 2 * inversion_step >= T:
        raise InvalidPoints(f"the thesis inversion uses frames N, N+{inversion_step}, N+{2 * inversion_step} for "
                            f"N = 0..{inversion_starts - 1}: needs {inversion_starts + 2 * inversion_step} frames, "
                            f"got {T}; lower inversion_step / inversion_starts")
    if not np.isfinite(tracks).all():
        raise InvalidPoints("the thesis method needs every marker in every frame (its BASIC program had no gaps); "
                            "use method='least_squares' for data with gaps")
    fixed, pairs = thesis_groups(tracks)
    tracks = _register(tracks, fixed[:2], reference_frame=0)           # "FORMALISE" on two fixed markers
    poles, spread = [], []
    for P, Q in pairs:
        ks = _thesis_frames(tracks[:, P], min_travel, 3)
        c = np.array([pole(tracks[a, P], tracks[b, P], tracks[a, Q], tracks[b, Q]) for a, b in zip(ks, ks[1:])])
        poles.append(c)
        spread.append(float(np.linalg.norm(np.diff(c, axis=0), axis=-1).sum()))
    ic = int(np.argmax(spread))
    sides = [k for k in range(3) if k != ic]
    sides.sort(key=lambda k: -_rotation_range(tracks[:, list(pairs[k])]))
    ii, io = sides
    P, Q = pairs[ic]
    ca, cs = pose2d(tracks[0, [P, Q]], tracks[:, [P, Q]])               # coupler frame = its pose at frame 0
    J = []
    for k in (ii, io):
        m = pairs[k][0]                                                  # the link's first marker, as in the listing
        local = to_body(ca, cs, tracks[:, m])                            # the inversion: coupler held fixed
        centres = []
        for N in range(inversion_starts):
            try:
                centres.append(circumcentre(local[N], local[N + inversion_step], local[N + 2 * inversion_step]))
            except DegenerateGeometry:      # two of the three relative positions coincide: no circle
                continue
        if not centres:
            raise DegenerateGeometry(f"the inversion found no circle for marker {m}: its positions relative to the "
                                     "coupler repeat at frames N, N+step, N+2 step; change inversion_step")
        J.append(np.mean(centres, axis=0))
    Jw = apply_pose(ca, cs, np.broadcast_to(np.array(J), (T, 2, 2)))
    G1, G2 = poles[ii].mean(0), poles[io].mean(0)
    names = {ii: "input", ic: "coupler", io: "output"}
    return _result(tracks, float("nan"), fixed, pairs[ii], pairs[ic], pairs[io], G1, G2, Jw[:, 0], Jw[:, 1],
                   False, "thesis", {names[k]: poles[k] for k in range(3)})


# ------------------------------------------------------------------------------------------------
# public entry point
# ------------------------------------------------------------------------------------------------
def reconstruct_four_bar(points: ArrayLike, method: Method = "least_squares", *, tol: float | None = None,
                         tracking: Literal["predictive", "nearest"] = "predictive", gate: float | None = None,
                         register: bool = True, refine: bool = True, min_travel: float = 32.0,
                         inversion_step: int = 10, inversion_starts: int = 10) -> FourBar:
    """Reconstruct a planar four-bar from unlabeled marker positions.

    Parameters
    ----------
    points : (T, M, 2) marker positions per frame, mm (any length unit; the lengths come out in
        it). Rows may be in any order in every frame; NaN rows are missing markers. Markers may sit
        anywhere on the links: at least two on each moving link and (for registration) two or more
        on the frame.
    method : ``"least_squares"`` (all frames, default) or ``"thesis"`` (Steps 1-5 of §5.5.1).
    tol : mm — rigidity tolerance (standard deviation of a rigid distance); default estimated from
        the noise (:func:`~.grouping.estimate_tolerance`). Least-squares method only.
    tracking : ``"predictive"`` (constant velocity + optimal assignment) or ``"nearest"`` (the
        thesis rule, valid only while every step is below half the smallest marker distance: the
        virtual lab's four-bar moves markers up to 26 mm per 12° frame past others 31 mm away,
        which breaks it).
    gate : mm — tracking gate (default: the smallest distance between two markers of a frame).
    register : least squares: map each frame onto the fixed markers first (the thesis always
        registers on two fixed markers).
    refine : least squares: fit the four-bar model to all marker positions (otherwise the circle-fit
        estimates are returned).
    min_travel : thesis: path length (mm) the first marker of a link covers between the frames of
        two successive poles (the listing's ``UN`` = 16 image units = 32 mm at Table 5.1's scale).
    inversion_step, inversion_starts : thesis: circumcentres of frames N, N+step, N+2 step for
        N = 0 .. starts-1 (10 and 10 in the listing, which needs 30 frames).

    Returns
    -------
    FourBar
        ``.lengths`` (``ground``, ``input``, ``coupler``, ``output``, mm), ``.ground_pivots``
        (2, 2), ``.joints`` (T, 4, 2) = G1, J1, J2, G2, ``.residuals`` (T, M) and ``.rms`` (mm).

    Raises
    ------
    InvalidPoints
        Not (T, M, 2), too few frames, or gaps for the thesis method.
    GroupingError
        The markers do not form a ground and three moving links.
    DegenerateGeometry
        A link barely moves, so its pivot or joint is undefined.

    Examples
    --------
    >>> from mirrorlab.plugins.mechanisms.synthetic import four_bar_positions
    >>> p = four_bar_positions(np.arange(30) * np.deg2rad(12))
    >>> rng = np.random.default_rng(0)
    >>> shuffled = np.stack([f[rng.permutation(len(f))] for f in p])
    >>> fb = reconstruct_four_bar(shuffled)
    >>> {k: round(v, 6) for k, v in fb.lengths.items()}
    {'ground': 230.0, 'input': 100.0, 'coupler': 220.0, 'output': 133.0}
    """
    if method not in ("least_squares", "thesis"):
        raise InvalidPoints(f"unknown method {method!r}; use 'least_squares' or 'thesis'")
    tracks = track_markers(points, tracking, gate)
    if method == "thesis":
        return _thesis(tracks, min_travel, inversion_step, inversion_starts)
    return _least_squares(tracks, tol, register, refine)

