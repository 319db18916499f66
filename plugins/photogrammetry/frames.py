"""Reconstruction of recorded 2-D marker data: (frames, markers, 2) image arrays with NaN for missing.

These functions adapt the per-chain / per-ray solvers of :mod:`.parallel`, :mod:`.central` and
:mod:`.mirror` to measured data: they skip missing markers (NaN in, NaN out), process all frames
at once, and report degenerate geometry with a typed error naming the **frame and marker** (indices
into the input arrays, 0-based; chain methods name the chain position, see each function).
Lengths in mm, angles in rad, one right-handed world frame.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .central import CentralCamera, reconstruct_chain_central
from .errors import DegenerateGeometry, InvalidArgument, PhotogrammetryError
from .mirror import mirror_normal, triangulate_mirror
from .parallel import reconstruct_chain_parallel

__all__ = ["image_to_film", "reconstruct_parallel_frames", "reconstruct_central_frames", "MirrorFrames",
           "reconstruct_mirror_frames", "mirror_normal_frames"]

FloatArray = NDArray[np.float64]


def _frames_xy(xy: ArrayLike, name: str) -> FloatArray:
    a = np.asarray(xy, dtype=float)
    if a.ndim == 2 and a.shape[-1] == 2:
        a = a[None]
    if a.ndim != 3 or a.shape[-1] != 2:
        raise InvalidArgument(f"{name} must have shape (frames, markers, 2), got {a.shape}")
    return a


def image_to_film(image_xy: ArrayLike, pixel_size: float = 1.0, principal_point: ArrayLike | None = None,
                  y_down: bool = False) -> FloatArray:
    """Image coordinates (any unit, e.g. px) to film coordinates in mm about the optical axis.

    ``film = (image - principal_point) * pixel_size``, with y negated when the image y axis points
    down (pixel rows) since the thesis film y points up.

    Examples
    --------
    >>> image_to_film([[110.0, 90.0]], 0.01, [100.0, 100.0], y_down=True).tolist()
    [[0.1, 0.1]]
    """
    xy = np.asarray(image_xy, dtype=float)
    pp = np.zeros(2) if principal_point is None else np.asarray(principal_point, float).reshape(2)
    film = (xy - pp) * pixel_size
    if y_down:
        film = film * np.array([1.0, -1.0])
    return film


def _renumber(exc: PhotogrammetryError, frames: NDArray[np.intp]) -> PhotogrammetryError:
    """The same error with sub-batch frame indices replaced by the caller's frame indices."""
    text = re.sub(r"frame (\d+)", lambda m: f"frame {int(frames[int(m.group(1))])}", str(exc))
    return type(exc)(text)


def _leading_valid(xy: FloatArray) -> NDArray[np.intp]:
    """Per frame, the number of leading markers with finite coordinates (a chain stops at a gap)."""
    seen = np.isfinite(xy).all(axis=-1)
    return np.where(seen.all(axis=1), seen.shape[1], np.argmin(seen, axis=1))


def _per_frame(a: ArrayLike | None, shape: tuple[int, ...], dtype: Any, name: str, needs: str) -> NDArray | None:
    """``a`` broadcast to ``shape`` (frames, ...); :class:`InvalidArgument` naming ``name`` when it does not fit."""
    if a is None:
        return None
    arr = np.asarray(a, dtype=dtype)
    try:
        return np.broadcast_to(arr, shape)
    except ValueError:
        raise InvalidArgument(f"{name} has shape {arr.shape}, but {needs}") from None


def reconstruct_parallel_frames(
    image_xy: ArrayLike, lengths: ArrayLike, magnification: float, signs: ArrayLike | None = None,
    tol_radicand: float = 1e-3,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Parallel-projection chains (eqs 2.7, 2.10–2.11) for every frame.

    Parameters
    ----------
    image_xy : array_like (frames, N, 2)
        Image coordinates (mm on the film, or any unit scaled by ``magnification``) of the chain
        markers 0..N-1; marker 0 is the reference marker and becomes the origin.
    lengths : array_like (N-1,) or (frames, N-1), mm
        Link n joins markers n-1 and n.
    magnification : float
        ``m = L / ell``: object mm per image unit.
    signs : array_like (N-1,) or (frames, N-1) of ±1
        ``+1`` when marker n lies further along the viewing direction than marker n-1 (never guessed).
    tol_radicand : float
        Clamp tolerance of eq. 2.10/2.11 (flagged ``segment_in_image_plane``).

    Returns
    -------
    points : (frames, N, 3) mm, NaN from the first missing marker of a frame on.
    in_plane : (frames, N) bool, the ``segment_in_image_plane`` flag (False for marker 0).

    Raises
    ------
    AmbiguousSign, InconsistentLength
        Naming the frame (input index) and the marker (chain position).

    Examples
    --------
    >>> pts, _ = reconstruct_parallel_frames([[[0, 0], [0.3, 0.4]]], [1.0], 1.0, [1])
    >>> np.round(pts, 6).tolist()
    [[[0.0, 0.0, 0.0], [0.3, 0.4, 0.866025]]]
    """
    xy = _frames_xy(image_xy, "image_xy")
    F, N = xy.shape[:2]
    needs = (f"image_xy has {F} frame(s) of {N} markers (0..{N - 1}): give {N - 1} per frame, shape ({N - 1},) or "
             f"({F}, {N - 1}) (link n joins markers n-1 and n)")
    D = _per_frame(lengths, (F, N - 1), float, "lengths", needs)
    s = _per_frame(signs, (F, N - 1), int, "signs", needs)
    points = np.full((F, N, 3), np.nan)
    in_plane = np.zeros((F, N), bool)
    count = _leading_valid(xy)
    points[count >= 1, 0] = 0.0
    for k in np.unique(count[count >= 2]):  # one vectorised call per chain length present
        frames = np.flatnonzero(count == k)
        rel = xy[frames, 1:k] - xy[frames, :1]
        try:
            r = reconstruct_chain_parallel(rel, D[frames, :k - 1], magnification,
                                           None if s is None else s[frames, :k - 1], tol_radicand=tol_radicand)
        except PhotogrammetryError as exc:
            raise _renumber(exc, frames) from exc
        points[frames, 1:k] = r.points
        in_plane[frames, 1:k] = r.flags["segment_in_image_plane"]
    return points, in_plane


def reconstruct_central_frames(
    image_xy: ArrayLike, lengths: ArrayLike, camera: CentralCamera, signs: ArrayLike | None = None,
    aux_xy: ArrayLike | None = None, aux_lengths: ArrayLike | None = None, start: ArrayLike | None = None,
    **tolerances: float,
) -> tuple[FloatArray, NDArray[np.int_], NDArray[np.bool_]]:
    """Central-projection chains (spec §3.3) for every frame.

    Parameters
    ----------
    image_xy : array_like (frames, N, 2), film mm
        Markers 1..N in chain order (column j is thesis marker j + 1; marker 0 is the reference
        point K, or ``start``, which is not imaged).
    lengths : array_like (N,) or (frames, N), mm
        ``lengths[j]`` joins marker j and marker j + 1 (the first from K).
    camera : CentralCamera
    signs : array_like (N,) or (frames, N) of {+1, -1, 0}, optional
        Root per link (0: decide by the auxiliary marker or fail).
    aux_xy : array_like (frames, N, 2), optional
        Auxiliary marker on each link (NaN where none), film mm; ``aux_lengths`` (N,) mm from the
        previous marker.
    start : array_like (3,), optional
        Chain start instead of K (mm).
    **tolerances
        ``tol_disc``, ``tol_z``, ``beta_max``, ``beta_sep`` of :func:`.reconstruct_chain_central`.

    Returns
    -------
    points : (frames, N, 3) mm, NaN from the first missing marker of a frame on.
    signs : (frames, N) int, sign used (0: coincident roots, mean taken, or not reconstructed).
    tangent : (frames, N) bool, ``tangent_ray`` flag.

    Raises
    ------
    AmbiguousSign, RayMissesSphere, NoValidRoot, RayNotForward
        Naming the frame (input index) and the marker (thesis number = column + 1).

    Examples
    --------
    >>> cam = CentralCamera(2687.0, 54.0, np.radians(12))
    >>> P = cam.K + np.array([[[0.0, 300.0, 0.0]]])
    >>> pts, s, t = reconstruct_central_frames(cam.project(P), [300.0], cam, signs=[-1])
    >>> bool(np.allclose(pts, P))
    True
    """
    xy = _frames_xy(image_xy, "image_xy")
    F, N = xy.shape[:2]
    needs = (f"image_xy has {F} frame(s) of {N} markers (1..{N}; K, marker 0, is not imaged): give {N} per frame, "
             f"shape ({N},) or ({F}, {N}), one per link, the first from K")
    if np.ndim(lengths) >= 1 and np.shape(lengths)[-1] == N - 1:
        needs += ("; image_xy has one marker more than lengths: if its first marker is K, leave it out "
                  "(column j of image_xy is chain marker j + 1)")
    D = _per_frame(lengths, (F, N), float, "lengths", needs)
    s = _per_frame(signs, (F, N), int, "signs", needs)
    axy = _per_frame(aux_xy, (F, N, 2), float, "aux_xy",
                     f"image_xy has {F} frame(s) of {N} markers: give ({F}, {N}, 2), one auxiliary marker per link")
    aD = _per_frame(aux_lengths, (F, N), float, "aux_lengths", needs)
    points = np.full((F, N, 3), np.nan)
    signs_out = np.zeros((F, N), int)
    tangent = np.zeros((F, N), bool)
    count = _leading_valid(xy)
    for k in np.unique(count[count >= 1]):
        frames = np.flatnonzero(count == k)
        try:
            r = reconstruct_chain_central(
                xy[frames, :k], D[frames, :k], camera, None if s is None else s[frames, :k],
                aux_xy=None if axy is None else axy[frames, :k], aux_lengths=None if aD is None else aD[frames, :k],
                start=start, **tolerances)
        except PhotogrammetryError as exc:
            raise _renumber(exc, frames) from exc
        points[frames, :k] = r.points
        signs_out[frames, :k] = r.signs
        tangent[frames, :k] = r.flags["tangent_ray"]
    return points, signs_out, tangent


def _frame_marker_list(frames: NDArray[np.intp], markers: NDArray[np.intp], limit: int = 5) -> str:
    pairs = ", ".join(f"frame {int(f)} marker {int(m)}" for f, m in zip(frames[:limit], markers[:limit]))
    more = f" and {frames.size - limit} more" if frames.size > limit else ""
    return pairs + more


def mirror_normal_frames(
    camera: Any, real_xy: ArrayLike, virtual_xy: ArrayLike, mirror_point: ArrayLike | None = None,
    method: Literal["lstsq", "thesis"] = "lstsq", per_frame: bool = False,
) -> tuple[FloatArray, FloatArray, NDArray[np.intp]]:
    """Mirror normal(s) from every marker seen both directly and in the mirror (eqs 3.8–3.10).

    Parameters
    ----------
    camera : camera model with ``camera_center`` and ``rays`` (plane calibration or pinhole).
    real_xy, virtual_xy : array_like (frames, markers, 2), image units
        Direct images and mirror images of the markers; NaN where not seen.
    mirror_point : array_like (3,), optional, mm
        A point on the mirror (orients the normal by 3.10).
    method : {"lstsq", "thesis"}
        Pooled estimate over all frames: least squares over all pairs, or the Appendix 2 average.
    per_frame : bool
        One normal per frame (least squares, all frames in one batched eigen-decomposition) for a
        mirror that moves.

    Returns
    -------
    normals : (3,) or (frames, 3); residuals : () or (frames,); pairs : () or (frames,) pairs used.

    Raises
    ------
    DegenerateGeometry
        Fewer than two pairs (in a frame), or pairs that leave the normal undetermined; names the frame.
    """
    real = _frames_xy(real_xy, "real_xy")
    virt = _frames_xy(virtual_xy, "virtual_xy")
    if real.shape != virt.shape:
        raise InvalidArgument(f"real_xy {real.shape} and virtual_xy {virt.shape} must have the same shape")
    both = np.isfinite(real).all(-1) & np.isfinite(virt).all(-1)
    fr, mk = np.nonzero(both)
    P = camera.rays(real[fr, mk])
    Pv = camera.rays(virt[fr, mk])
    F1 = np.asarray(camera.camera_center, float)
    if not per_frame:
        res = mirror_normal(P, Pv, mirror_point=mirror_point, camera_center=None if mirror_point is None else F1,
                            method=method)
        return res.normal, np.float64(res.residual), np.intp(res.n_pairs)
    if method != "lstsq":
        raise InvalidArgument("per-frame normals use method='lstsq'; the thesis average pools all frames")
    F = real.shape[0]
    pairs = np.bincount(fr, minlength=F)
    few = np.flatnonzero(pairs < 2)
    if few.size:
        raise DegenerateGeometry(
            f"frame{'s' if few.size > 1 else ''} {', '.join(map(str, few[:8]))}: fewer than two markers seen both "
            "directly and in the mirror; the mirror normal of a frame needs two pairs (or give a fixed normal)")
    A = np.cross(P, Pv)
    norm = np.linalg.norm(A, axis=1)
    bad = np.flatnonzero(norm < 1e-6)
    if bad.size:
        raise DegenerateGeometry(f"{_frame_marker_list(fr[bad], mk[bad])}: marker and mirror-image rays are parallel; "
                                 "the marker is on the camera's normal line to the mirror or the pairing is wrong")
    A /= norm[:, None]
    S = np.zeros((F, 3, 3))
    np.add.at(S, fr, A[:, :, None] * A[:, None, :])  # scatter matrix of the pair planes per frame
    w, v = np.linalg.eigh(S)
    weak = np.flatnonzero(w[:, 1] < 1e-12 * np.maximum(w[:, 2], 1e-300))
    if weak.size:
        raise DegenerateGeometry(f"frame {int(weak[0])}: all marker/mirror-image pairs are coplanar with the mirror "
                                 "normal, which is then undetermined; use markers spread off that plane")
    n = v[:, :, 0]
    toward = (np.asarray(mirror_point, float) - F1)[None] if mirror_point is not None else \
        np.add.reduceat(Pv[np.argsort(fr, kind="stable")], np.r_[0, np.cumsum(pairs)[:-1]], axis=0)
    n = np.where((np.einsum("fi,fi->f", np.broadcast_to(toward, n.shape), n) > 0)[:, None], -n, n)  # (3.10)
    resid = np.sqrt(np.bincount(fr, np.einsum("pi,pi->p", A, n[fr]) ** 2, minlength=F) / pairs)
    return n, resid, pairs


@dataclass(frozen=True)
class MirrorFrames:
    """Result of :func:`reconstruct_mirror_frames` (all arrays per frame and marker, NaN where not seen).

    Attributes
    ----------
    points : (frames, markers, 3) mm.
    gap : (frames, markers) mm, miss distance between the real and the reflected mirror ray.
    angle : (frames, markers) rad, intersection angle of the two rays.
    normal : (3,) or (frames, 3), the mirror normal used (toward the camera).
    virtual_center : (3,) or (frames, 3) mm, the virtual camera F2.
    reprojection : (frames, markers) px RMS (``method="optimal"``; NaN otherwise).
    """

    points: FloatArray
    gap: FloatArray
    angle: FloatArray
    normal: FloatArray
    virtual_center: FloatArray
    reprojection: FloatArray


def reconstruct_mirror_frames(
    camera: Any, real_xy: ArrayLike, virtual_xy: ArrayLike, mirror_point: ArrayLike, normal: ArrayLike,
    method: Literal["midpoint", "optimal"] = "midpoint", max_gap: float | None = None,
    on_degenerate: Literal["raise", "nan"] = "raise", parallel_tol: float = 1e-12,
) -> MirrorFrames:
    """Markers of every frame from one camera and one plane mirror (thesis §3.2, spec §9 steps 5–6).

    Parameters
    ----------
    camera : camera model with ``camera_center``, ``rays`` and ``project`` (plane calibration or pinhole).
    real_xy, virtual_xy : array_like (frames, markers, 2), image units (px)
        Direct image and mirror image of each marker; NaN where not seen (the output is NaN there).
    mirror_point : array_like (3,), mm — G on the reflecting surface.
    normal : array_like (3,) or (frames, 3) — mirror normal toward the camera (one per frame for a
        moving mirror).
    method : {"midpoint", "optimal"}
        Thesis midpoint (3.5)–(3.7), or reprojection-optimal (fixed mirror only).
    max_gap : float, optional, mm
        Reject markers whose rays miss each other by more than this.
    on_degenerate : {"raise", "nan"}
        Degenerate markers (parallel rays, behind a camera, gap above ``max_gap``) raise
        :class:`DegenerateGeometry` naming frame and marker, or become NaN.

    Returns
    -------
    MirrorFrames

    Examples
    --------
    >>> from mirrorlab.plugins.photogrammetry.cameras import PinholeCamera
    >>> from mirrorlab.plugins.photogrammetry.mirror import reflect
    >>> cam = PinholeCamera(np.array([[1000., 0, 320], [0, 1000., 240], [0, 0, 1]]), np.zeros(5),
    ...                     np.diag([1., -1., -1.]), np.array([0., 0., 1000.]))
    >>> G, n = np.array([-400., 0., 0.]), np.array([1., 0., 0.])
    >>> V = np.array([[[100., 50., 300.], [-150., -100., 200.]]])
    >>> r = reconstruct_mirror_frames(cam, cam.project(V[0])[None], cam.project(reflect(V[0], G, n))[None], G, n)
    >>> bool(np.allclose(r.points, V)), bool(np.nanmax(r.gap) < 1e-9)
    (True, True)
    """
    real = _frames_xy(real_xy, "real_xy")
    virt = _frames_xy(virtual_xy, "virtual_xy")
    if real.shape != virt.shape:
        raise InvalidArgument(f"real_xy {real.shape} and virtual_xy {virt.shape} must have the same shape")
    F, M = real.shape[:2]
    G = np.asarray(mirror_point, float).reshape(3)
    nrm = np.asarray(normal, float)
    per_frame = nrm.ndim == 2
    if per_frame and nrm.shape != (F, 3):
        raise InvalidArgument(f"normal must have shape (3,) or ({F}, 3), got {nrm.shape}")
    if per_frame and method == "optimal":
        raise InvalidArgument("method='optimal' needs one fixed mirror normal; use 'midpoint' for per-frame normals")
    seen = np.isfinite(real).all(-1) & np.isfinite(virt).all(-1)
    fr, mk = np.nonzero(seen)
    u1 = camera.rays(real[fr, mk])
    u2p = camera.rays(virt[fr, mk])
    F1 = np.asarray(camera.camera_center, float)
    if per_frame:
        nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
        dist = (F1 - G) @ nrm.T
        wrong = np.flatnonzero(dist <= 0)
        if wrong.size:
            raise DegenerateGeometry(f"frame {int(wrong[0])}: the mirror normal points away from the camera or the "
                                     "camera lies in the mirror plane (eq. 3.10); flip the normal or check the mirror point")
        centers = F1 - 2.0 * dist[:, None] * nrm  # (3.11) per frame
        normals_pt = nrm[fr]
        u2 = u2p - 2.0 * np.einsum("pi,pi->p", u2p, normals_pt)[:, None] * normals_pt  # (3.13)
    kw = dict(parallel_tol=parallel_tol, max_gap=max_gap)
    try:
        if per_frame:
            res = _triangulate_per_point(F1, centers[fr], u1, u2, **kw)
        else:
            res = triangulate_mirror(F1, G, nrm, u1, u2p, method, camera=camera, image_xy_real=real[fr, mk],
                                     image_xy_virtual=virt[fr, mk], on_degenerate="flag", **kw)
    except ValueError as exc:  # shape/finite checks of the solver: a usage problem of ours
        raise InvalidArgument(str(exc)) from exc
    bad = np.asarray(res["degenerate"] if per_frame else res.degenerate)
    if bad.any() and on_degenerate == "raise":
        idx = np.flatnonzero(bad)
        reason = _degenerate_reason(F1, G if not per_frame else None, nrm if not per_frame else None,
                                    u1[idx], u2p[idx] if not per_frame else u2[idx],
                                    None if not per_frame else centers[fr[idx]], kw)
        raise DegenerateGeometry(f"{_frame_marker_list(fr[idx], mk[idx])}: {reason}")
    get = (lambda k: res[k]) if per_frame else (lambda k: getattr(res, k))
    points = np.full((F, M, 3), np.nan)
    gap = np.full((F, M), np.nan)
    angle = np.full((F, M), np.nan)
    rep = np.full((F, M), np.nan)
    points[fr, mk] = get("points")
    gap[fr, mk] = np.where(bad, np.nan, get("gap"))
    angle[fr, mk] = np.where(bad, np.nan, np.arccos(np.minimum(get("cos_angle"), 1.0)))
    if not per_frame and res.reprojection is not None:
        rep[fr, mk] = res.reprojection
    if per_frame:
        return MirrorFrames(points, gap, angle, nrm, centers, rep)
    return MirrorFrames(points, gap, angle, nrm / np.linalg.norm(nrm), res.virtual_center, rep)


def _triangulate_per_point(F1: FloatArray, F2: FloatArray, u1: FloatArray, u2: FloatArray,
                           parallel_tol: float, max_gap: float | None) -> dict[str, Any]:
    """Midpoint triangulation with a virtual camera per point (already reflected rays)."""
    from .mirror import intersect_rays

    origins = np.stack([np.broadcast_to(F1, F2.shape), F2], axis=1)
    hit = intersect_rays(origins, [u1, u2], parallel_tol=parallel_tol, on_degenerate="flag")
    gap = 2.0 * hit.residual
    bad = hit.degenerate.copy()
    if max_gap is not None:
        bad |= np.nan_to_num(gap) > max_gap
    points = np.where(bad[:, None], np.nan, hit.points)
    return {"points": points, "gap": gap, "cos_angle": hit.cos_angle, "degenerate": bad}


def _degenerate_reason(F1, G, n, u1, u2, F2, kw) -> str:
    """Why the flagged markers are degenerate: the solver's own message for the first of them."""
    try:
        if F2 is None:
            triangulate_mirror(F1, G, n, u1[:1], u2[:1], on_degenerate="raise", **kw)
        else:
            from .mirror import intersect_rays

            intersect_rays(np.stack([F1, F2[0]]), [u1[:1], u2[:1]], parallel_tol=kw["parallel_tol"],
                           on_degenerate="raise")
            return f"real and mirror rays miss each other by more than max_gap = {kw['max_gap']:g} mm"
    except DegenerateGeometry as exc:
        return str(exc).split(": ", 1)[-1]
    return "degenerate geometry"
