"""Central-projection photogrammetry of a marker chain (thesis §2.3, eqs 2.12–2.28 corrected; spec §3).

World frame (spec §3.1): right-handed, Y vertical up, Z horizontal in the viewing direction,
X = Y x Z. The projection centre is S = (0, L sin(alpha), 0), the reference point
K = (0, 0, L cos(alpha)) with |SK| = L; the tilt alpha (rad) is positive when the camera looks
down. Film coordinates (x, y) are in mm on the positive image at distance ell in front of S,
x along +X, y upward. All lengths in mm.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import (
    AmbiguousSign,
    InvalidArgument,
    InvalidCamera,
    NoValidRoot,
    RayMissesSphere,
    RayNotForward,
)

__all__ = [
    "object_image_distances",
    "film_to_perspective",
    "perspective_to_world",
    "link_coefficients",
    "CentralCamera",
    "CentralChainResult",
    "reconstruct_chain_central",
]

SignResolver = Callable[[int, int, NDArray[np.float64]], int]


def object_image_distances(a: ArrayLike, f: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Object distance L and image distance ell from a = L + ell and the thin-lens law (eqs 2.25–2.28).

    Parameters
    ----------
    a : array_like
        Measured distance film -> reference point K (mm).
    f : array_like
        Focal length (mm); requires ``a >= 4 f``.

    Returns
    -------
    L, ell : ndarray
        Object and image distance (mm).

    Raises
    ------
    InvalidCamera
        ``a <= 0``, ``f <= 0`` or ``a < 4 f`` (no real focus solution).

    Examples
    --------
    >>> L, ell = object_image_distances(2687.0, 54.0)
    >>> round(float(L), 3), round(float(ell), 3)
    (2631.869, 55.131)
    """
    a = np.asarray(a, dtype=float)
    f = np.asarray(f, dtype=float)
    if np.any(a <= 0) or np.any(f <= 0) or np.any(a < 4 * f):
        raise InvalidCamera(
            f"a = {a} mm and f = {f} mm admit no real focus (need a > 0, f > 0, a >= 4 f); "
            "check the shooting distance and the focal length"
        )
    root = np.sqrt(a * a - 4 * f * a)
    return (a + root) / 2, (a - root) / 2


def film_to_perspective(
    image_xy: ArrayLike, ell: float, alpha: float
) -> NDArray[np.float64]:
    """Two-point (tilted film) to single-point perspective coordinates (eqs 2.13, 2.15, explicit forms).

    Parameters
    ----------
    image_xy : array_like, shape (..., 2)
        Film coordinates (x, y) in mm.
    ell : float
        Image distance (mm).
    alpha : float
        Camera tilt (rad), positive looking down.

    Returns
    -------
    ndarray, shape (..., 2)
        ``(x', y')`` on the vertical plane at horizontal distance ``ell cos(alpha)`` from S (mm).

    Raises
    ------
    RayNotForward
        ``ell cos(alpha) + y sin(alpha) <= 0`` (the film point's ray does not reach the vertical plane).

    Examples
    --------
    >>> film_to_perspective([[0.0, 0.0]], 55.0, 0.2).tolist()
    [[0.0, 0.0]]
    """
    xy = np.asarray(image_xy, dtype=float)
    den = ell * np.cos(alpha) + xy[..., 1] * np.sin(alpha)
    if np.any(den <= 0):
        idx = np.argwhere(np.atleast_1d(den <= 0))[0]
        raise RayNotForward(
            f"image point index {tuple(int(i) for i in idx)}: ell cos(alpha) + y sin(alpha) <= 0, the ray "
            "points away from the scene; check the sign of y (upward) and of alpha (down-tilt positive)"
        )
    xp = ell * xy[..., 0] * np.cos(alpha) / den
    yp = ell * xy[..., 1] / den
    return np.stack([xp, yp], axis=-1)


def perspective_to_world(
    perspective_xy: ArrayLike, Z: ArrayLike, L: float, ell: float, alpha: float
) -> NDArray[np.float64]:
    """World point on the ray of a single-point-perspective image point at depth Z (eqs 2.18, 2.20).

    Parameters
    ----------
    perspective_xy : array_like, shape (..., 2)
        ``(x', y')`` (mm).
    Z : array_like, shape (...)
        World Z (mm).
    L, ell : float
        Object and image distance (mm).
    alpha : float
        Tilt (rad).

    Returns
    -------
    ndarray, shape (..., 3)
        (X, Y, Z) in mm.

    Examples
    --------
    >>> perspective_to_world([[0.0, 0.0]], [100.0], 1000.0, 50.0, 0.0).tolist()
    [[0.0, 0.0, 100.0]]
    """
    p = np.asarray(perspective_xy, dtype=float)
    Z = np.asarray(Z, dtype=float)
    c = ell * np.cos(alpha)
    X = p[..., 0] / c * Z  # (2.18)
    Y = p[..., 1] * Z / c + (L * np.cos(alpha) - Z) * np.tan(alpha)  # (2.20)
    return np.stack(np.broadcast_arrays(X, Y, Z), axis=-1)


def link_coefficients(
    xp: ArrayLike,
    yp: ArrayLike,
    xp_prev: ArrayLike,
    yp_prev: ArrayLike,
    Z_prev: ArrayLike,
    a_prev: ArrayLike,
    D: ArrayLike,
    ell: float,
    alpha: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Coefficients a_i, b_i, c_i of the link quadratic, written as in (2.23) (corrected b_i).

    ``Z_i = (-b_i ± sqrt(b_i**2 - a_i c_i)) / a_i`` (2.22). Provided for the thesis form; the solver
    uses the equivalent ray-sphere form ``a = |w|^2``, ``b = -w.(P_prev - S)``.

    Examples
    --------
    >>> a, b, c = link_coefficients(0, 0, 0, 0, 1000.0, 1.0, 100.0, 50.0, 0.0)
    >>> float(a), float(b), float(c)
    (1.0, -1000.0, 990000.0)
    """
    xp, yp, xq, yq, Zq, aq, D = (np.asarray(v, dtype=float) for v in (xp, yp, xp_prev, yp_prev, Z_prev, a_prev, D))
    s, c = np.sin(alpha), np.cos(alpha)
    a = ((xp**2 + yp**2) / ell**2 - 2 * yp * s / ell + 1) / c**2
    b = Zq * (-(xp * xq + yp * yq) / (ell**2 * c**2) + s / (ell * c**2) * (yp + yq) - np.tan(alpha) ** 2 - 1)
    cc = aq * Zq**2 - D**2
    return a, b, cc


@dataclass(frozen=True)
class CentralCamera:
    """Tilted central-projection camera of thesis §2.3 (spec §3.1).

    Parameters
    ----------
    a : float
        Distance film -> reference point K (mm).
    f : float
        Focal length (mm).
    alpha : float
        Tilt of the optical axis below the horizontal (rad).

    Examples
    --------
    >>> cam = CentralCamera(2687.0, 54.0, np.radians(12))
    >>> np.round(cam.project([cam.K + [0, 300, 0]]), 5).tolist()
    [[0.0, 6.29615]]
    """

    a: float
    f: float
    alpha: float

    def __post_init__(self) -> None:
        object_image_distances(self.a, self.f)  # validates

    @property
    def L(self) -> float:
        """Object distance of K (mm), eq. 2.27."""
        return float(object_image_distances(self.a, self.f)[0])

    @property
    def ell(self) -> float:
        """Image distance (mm), eq. 2.28."""
        return float(object_image_distances(self.a, self.f)[1])

    @property
    def camera_center(self) -> NDArray[np.float64]:
        """Projection centre S = (0, L sin(alpha), 0) (mm)."""
        return np.array([0.0, self.L * np.sin(self.alpha), 0.0])

    S = camera_center

    @property
    def K(self) -> NDArray[np.float64]:
        """Reference point K = (0, 0, L cos(alpha)) (mm), the chain start (2.24)."""
        return np.array([0.0, 0.0, self.L * np.cos(self.alpha)])

    @property
    def axes(self) -> NDArray[np.float64]:
        """Rows: film x axis, film y axis (upward), optical axis d (unit vectors, world frame)."""
        s, c = np.sin(self.alpha), np.cos(self.alpha)
        return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])

    def project(self, points: ArrayLike) -> NDArray[np.float64]:
        """Film coordinates (mm) of world points (..., 3); raises RayNotForward behind the camera."""
        v = np.asarray(points, dtype=float) - self.camera_center
        cam = v @ self.axes.T
        if np.any(cam[..., 2] <= 0):
            idx = np.argwhere(np.atleast_1d(cam[..., 2] <= 0))[0]
            raise RayNotForward(f"point index {tuple(int(i) for i in idx)} lies behind the camera; it cannot be imaged")
        return self.ell * cam[..., :2] / cam[..., 2:3]

    def ray_vectors(self, image_xy: ArrayLike) -> NDArray[np.float64]:
        """Ray directions w = (x'/(ell cos a), y'/(ell cos a) - tan a, 1) with unit Z component."""
        p = film_to_perspective(image_xy, self.ell, self.alpha)
        c = self.ell * np.cos(self.alpha)
        return np.stack(
            [p[..., 0] / c, p[..., 1] / c - np.tan(self.alpha), np.ones(p.shape[:-1])], axis=-1
        )

    def rays(self, image_xy: ArrayLike) -> NDArray[np.float64]:
        """Unit world rays (..., 3) from S through the film points (..., 2)."""
        w = self.ray_vectors(image_xy)
        return w / np.linalg.norm(w, axis=-1, keepdims=True)


@dataclass(frozen=True)
class CentralChainResult:
    """Result of :func:`reconstruct_chain_central`.

    Attributes
    ----------
    points : ndarray, shape (..., N, 3)
        Reconstructed markers 1..N (mm).
    candidates : ndarray, shape (..., N, 2, 3)
        Both ray-sphere intersections per link: index 0 the ``+`` root (larger Z), 1 the ``-`` root.
    signs : ndarray of int, shape (..., N)
        Sign chosen (+1/-1; 0 where the roots coincide and their mean was taken).
    flags : dict of bool arrays (..., N)
        ``tangent_ray`` (discriminant clamped or roots closer than ``tol_z``), ``forced_root`` (one
        root behind the camera), ``by_aux_marker`` (decided by §3.4), ``discriminant_ratio``
        (float array: Delta / b**2).
    """

    points: NDArray[np.float64]
    candidates: NDArray[np.float64]
    signs: NDArray[np.int_]
    flags: dict = field(default_factory=dict)


def _roots(camera: CentralCamera, w: NDArray, prev: NDArray, D: NDArray, tol_disc: float, frames: NDArray,
           link: int, what: str):
    """Ray-sphere roots Z± (vectorised over frames); w: (F,3), prev: (F,3), D: (F,)."""
    Q = prev - camera.camera_center
    a = np.sum(w * w, axis=-1)
    b = -np.sum(w * Q, axis=-1)
    c = np.sum(Q * Q, axis=-1) - D**2
    disc = b * b - a * c
    ratio = disc / (b * b)
    miss = disc < -tol_disc * b * b
    if np.any(miss):
        k = int(np.argmax(miss))
        raise RayMissesSphere(
            f"frame {int(frames[k])}, {what} {link}: the ray does not reach the sphere of radius "
            f"{D[k]:.4g} mm about the previous marker (Delta/b^2 = {ratio[k]:.3g}); "
            "check the link length and the image coordinates of this marker"
        )
    tangent = disc < 0
    sq = np.sqrt(np.maximum(disc, 0.0))
    Zp, Zm = (-b + sq) / a, (-b - sq) / a
    cand = camera.camera_center + np.stack([Zp, Zm], axis=-1)[..., None] * w[:, None, :]
    depth = (cand - camera.camera_center) @ camera.axes[2]
    return cand, depth > 0, tangent, ratio


def reconstruct_chain_central(
    image_xy: ArrayLike,
    lengths: ArrayLike,
    camera: CentralCamera,
    signs: ArrayLike | None = None,
    aux_xy: ArrayLike | None = None,
    aux_lengths: ArrayLike | None = None,
    resolver: SignResolver | None = None,
    reference: ArrayLike | None = None,
    start: ArrayLike | None = None,
    tol_disc: float = 1e-6,
    tol_z: float = 0.5,
    beta_max: float = np.radians(2.0),
    beta_sep: float = np.radians(1.0),
) -> CentralChainResult:
    """Reconstruct a chain of markers with known link lengths from one tilted central projection (spec §3.3).

    Parameters
    ----------
    image_xy : array_like, shape (..., N, 2)
        Film coordinates (mm) of markers 1..N in chain order from K; leading axes are frames.
    lengths : array_like, shape (N,) or (..., N)
        Link lengths D_i (mm); D_1 is measured from K (or from ``start``).
    camera : CentralCamera
        Camera (a, f, alpha).
    signs : array_like of {+1, -1, 0}, optional
        Root per link: +1 the larger-Z root, -1 the smaller; 0 = undecided (use the other means).
    aux_xy : array_like, shape (..., N, 2), optional
        Film coordinates of an auxiliary marker on link i (NaN where a link has none), §3.4.
    aux_lengths : array_like, shape (N,) or (..., N), optional
        Distances D_i* (mm) of the auxiliary markers from the previous marker (0 < D_i* < D_i).
    resolver : callable, optional
        ``resolver(frame, link, candidates(2, 3)) -> +1 | -1`` for links still undecided.
    reference : array_like, shape (..., N, 3), optional
        Pick, for every link without a given sign, the root closest to this point (used by the error
        analysis to follow the unperturbed solution; takes precedence over the mean of near-coincident
        roots).
    start : array_like, shape (3,) or (..., 3), optional
        Position of marker 0 (default K, eq. 2.24).
    tol_disc : float
        Relative tolerance on the discriminant (``Delta >= -tol_disc b**2`` is clamped to 0).
    tol_z : float
        Roots closer than this (mm) count as coincident: their mean is used, flag ``tangent_ray``.
    beta_max, beta_sep : float
        Acceptance thresholds (rad) of the auxiliary-marker test (§3.4).

    Returns
    -------
    CentralChainResult

    Raises
    ------
    InvalidCamera, RayNotForward, RayMissesSphere, NoValidRoot, AmbiguousSign
        Each names the frame and the marker and says what to check. Never picks a sign silently.

    Examples
    --------
    >>> cam = CentralCamera(2687.0, 54.0, np.radians(12))
    >>> P = cam.K + [[0.0, 300.0, 0.0]]
    >>> r = reconstruct_chain_central(cam.project(P), [300.0], cam, signs=[-1])
    >>> np.allclose(r.points, P)
    True
    """
    xy = np.asarray(image_xy, dtype=float)
    if xy.ndim < 2 or xy.shape[-1] != 2:
        raise InvalidArgument(f"image_xy must have shape (..., N, 2); got {xy.shape}")
    batch, n = xy.shape[:-2], xy.shape[-2]
    F = int(np.prod(batch, dtype=int))
    xy2 = xy.reshape(F, n, 2)
    D = np.broadcast_to(np.asarray(lengths, dtype=float), batch + (n,)).reshape(F, n)
    if np.any(D <= 0):
        raise InvalidArgument("link lengths must be > 0 (mm)")
    s_in = np.zeros((F, n), dtype=int) if signs is None else np.broadcast_to(
        np.asarray(signs), batch + (n,)).reshape(F, n).astype(int)
    if np.any((s_in != 0) & (np.abs(s_in) != 1)):
        raise InvalidArgument("signs must be +1, -1 or 0 (undecided)")
    frames = np.arange(F)
    den = camera.ell * np.cos(camera.alpha) + xy2[..., 1] * np.sin(camera.alpha)  # step 2 of spec §3.3
    if np.any(den <= 0):
        f, i = np.argwhere(den <= 0)[0]
        raise RayNotForward(
            f"frame {f}, marker {i + 1}: ell cos(alpha) + y sin(alpha) = {den[f, i]:.4g} <= 0, the ray does not "
            "point into the scene; check the sign of y (upward) and of alpha (down-tilt positive)"
        )
    W = camera.ray_vectors(xy2)  # (F, n, 3)
    have_aux = aux_xy is not None
    if have_aux:
        if aux_lengths is None:
            raise InvalidArgument("aux_xy needs aux_lengths (distance of each auxiliary marker from the previous marker)")
        axy = np.broadcast_to(np.asarray(aux_xy, dtype=float), batch + (n, 2)).reshape(F, n, 2)
        aD = np.broadcast_to(np.asarray(aux_lengths, dtype=float), batch + (n,)).reshape(F, n)
        aux_present = np.all(np.isfinite(axy), axis=-1)
        Wa = camera.ray_vectors(np.where(aux_present[..., None], axy, 0.0))
    ref = None if reference is None else np.broadcast_to(
        np.asarray(reference, dtype=float), batch + (n, 3)).reshape(F, n, 3)

    prev = np.broadcast_to(camera.K if start is None else np.asarray(start, dtype=float), batch + (3,)).reshape(F, 3)
    prev = prev.copy()
    pts = np.empty((F, n, 3))
    cands = np.empty((F, n, 2, 3))
    signs_out = np.zeros((F, n), dtype=int)
    flag_tan = np.zeros((F, n), bool)
    flag_forced = np.zeros((F, n), bool)
    flag_aux = np.zeros((F, n), bool)
    ratios = np.zeros((F, n))
    for i in range(n):  # sequential along the chain, vectorised over frames
        marker = i + 1
        cand, valid, tangent, ratio = _roots(camera, W[:, i], prev, D[:, i], tol_disc, frames, marker, "marker")
        cands[:, i], ratios[:, i] = cand, ratio
        none = ~valid.any(axis=1)
        if np.any(none):
            k = int(np.argmax(none))
            raise NoValidRoot(
                f"frame {k}, marker {marker}: both ray-sphere intersections lie behind the camera; "
                "check the camera tilt sign and the image coordinates"
            )
        coincide = tangent | (np.abs(cand[:, 0, 2] - cand[:, 1, 2]) < tol_z)
        forced = valid.sum(axis=1) == 1
        choice = np.where(forced, np.where(valid[:, 0], 1, -1), 0)
        given = s_in[:, i]
        bad = (given != 0) & ~valid[np.arange(F), np.where(given == 1, 0, 1)]
        if np.any(bad):
            k = int(np.argmax(bad))
            raise NoValidRoot(
                f"frame {k}, marker {marker}: the root with the given sign {int(given[k]):+d} lies behind "
                "the camera; use the other sign"
            )
        choice = np.where(given != 0, given, choice)
        undecided = (choice == 0) & ~coincide
        if have_aux and np.any(undecided & aux_present[:, i]):
            sel = undecided & aux_present[:, i]
            ca, va, _, _ = _roots(camera, Wa[sel, i], prev[sel], aD[sel, i], tol_disc, frames[sel], marker,
                                  "auxiliary marker on link to marker")
            e = (cand[sel] - prev[sel, None]) / D[sel, i, None, None]  # (m, 2, 3)
            es = (ca - prev[sel, None]) / aD[sel, i, None, None]
            q = np.einsum("msk,mtk->mst", e, es)
            q = np.where(valid[sel][:, :, None] & va[:, None, :], q, -np.inf)
            best = q.max(axis=2)  # per sigma
            sig = np.argmax(best, axis=1)
            q1 = best[np.arange(len(sig)), sig]
            q2 = best[np.arange(len(sig)), 1 - sig]
            ang1 = np.arccos(np.clip(q1, -1, 1))
            ang2 = np.where(np.isfinite(q2), np.arccos(np.clip(q2, -1, 1)), np.pi)
            ok = (q1 >= np.cos(beta_max)) & (ang2 - ang1 >= beta_sep)
            if not np.all(ok):
                k = int(np.argmin(ok))
                raise AmbiguousSign(
                    f"frame {int(frames[sel][k])}, marker {marker}: the auxiliary marker does not decide the "
                    f"root (best misalignment {np.degrees(ang1[k]):.2f} deg, other root "
                    f"{np.degrees(ang2[k]):.2f} deg); candidates Z = {cand[sel][k, :, 2].round(3).tolist()} mm; "
                    "give the sign explicitly or move the auxiliary marker"
                )
            choice[sel] = np.where(sig == 0, 1, -1)
            flag_aux[sel, i] = True
            undecided = (choice == 0) & ~coincide
        if ref is not None:  # also for near-coincident roots: follow the reference exactly
            d = np.linalg.norm(cand - ref[:, i, None, :], axis=-1)
            d = np.where(valid, d, np.inf)
            choice = np.where(choice == 0, np.where(d[:, 0] <= d[:, 1], 1, -1), choice)
            undecided = (choice == 0) & ~coincide
        if np.any(undecided):
            if resolver is None:
                k = int(np.argmax(undecided))
                raise AmbiguousSign(
                    f"frame {k}, marker {marker}: two valid roots Z = {cand[k, :, 2].round(3).tolist()} mm; "
                    "pass signs=[...], an auxiliary marker (aux_xy, aux_lengths) or a resolver callable"
                )
            for k in np.flatnonzero(undecided):
                c = int(resolver(int(k), marker, cand[k].copy()))
                if c not in (1, -1):
                    raise AmbiguousSign(f"frame {k}, marker {marker}: resolver returned {c!r}, not +1/-1")
                choice[k] = c
        mean = (choice == 0) & coincide
        P = np.where((choice == 1)[:, None], cand[:, 0], cand[:, 1])
        P = np.where(mean[:, None], cand.mean(axis=1), P)
        pts[:, i], signs_out[:, i] = P, choice
        flag_tan[:, i], flag_forced[:, i] = coincide, forced & (given == 0)
        prev = P
    flags = {
        "tangent_ray": flag_tan.reshape(batch + (n,)),
        "forced_root": flag_forced.reshape(batch + (n,)),
        "by_aux_marker": flag_aux.reshape(batch + (n,)),
        "discriminant_ratio": ratios.reshape(batch + (n,)),
    }
    return CentralChainResult(
        pts.reshape(batch + (n, 3)), cands.reshape(batch + (n, 2, 3)), signs_out.reshape(batch + (n,)), flags
    )
