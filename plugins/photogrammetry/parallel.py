"""Parallel-projection photogrammetry (thesis §2.2, eqs 2.1–2.11; spec §1–2).

Conventions: lengths in mm (or any one consistent unit), angles in rad. The reconstruction frame
has its origin at the reference marker 0 (image origin), X, Y parallel to the image axes x, y and
Z along the viewing direction (right-handed when x, y, Z are).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import AmbiguousSign, InconsistentLength, InvalidArgument

__all__ = [
    "relative_image_error",
    "min_shooting_distance_translation",
    "min_shooting_distance_rotation",
    "ParallelChainResult",
    "reconstruct_chain_parallel",
    "SignResolver",
]

#: ``resolver(frame, link, candidates) -> +1 | -1``; ``candidates`` is a (2, 3) array holding the
#: point of marker ``link`` for sign +1 (row 0) and sign -1 (row 1).
SignResolver = Callable[[int, int, NDArray[np.float64]], int]


def relative_image_error(L: ArrayLike, delta_L: ArrayLike) -> NDArray[np.float64]:
    """Relative shrinkage of an image length when the object recedes by ``delta_L`` (eq. 2.2).

    Parameters
    ----------
    L : array_like
        Object distance (mm), > 0.
    delta_L : array_like
        Displacement of the object away from the camera (mm), >= 0.

    Returns
    -------
    ndarray
        ``eps = delta_L / (L + delta_L)`` (dimensionless).

    Examples
    --------
    >>> round(float(relative_image_error(20.0, 0.5)), 7)
    0.0243902
    """
    L = np.asarray(L, dtype=float)
    delta_L = np.asarray(delta_L, dtype=float)
    if np.any(L <= 0) or np.any(delta_L < 0):
        raise InvalidArgument("relative_image_error needs L > 0 and delta_L >= 0; check the distances")
    return delta_L / (L + delta_L)


def min_shooting_distance_translation(delta_L: ArrayLike, eps_max: ArrayLike) -> NDArray[np.float64]:
    """Minimum object distance for a tolerated relative image error (eq. 2.3).

    Parameters
    ----------
    delta_L : array_like
        Range of object displacement along the viewing direction (mm), >= 0.
    eps_max : array_like
        Tolerated relative error of the image length, 0 < eps_max < 1.

    Returns
    -------
    ndarray
        ``L_min = (1 - eps_max) / eps_max * delta_L`` in the unit of ``delta_L``.

    Examples
    --------
    >>> float(min_shooting_distance_translation(0.5, 0.01))
    49.5
    """
    delta_L = np.asarray(delta_L, dtype=float)
    eps_max = np.asarray(eps_max, dtype=float)
    if np.any(delta_L < 0):
        raise InvalidArgument("delta_L must be >= 0 (a displacement range); pass its absolute value")
    if np.any((eps_max <= 0) | (eps_max >= 1)):
        raise InvalidArgument("eps_max must lie in (0, 1); e.g. 0.01 for a 1 % reading error")
    return (1.0 - eps_max) / eps_max * delta_L


def min_shooting_distance_rotation(
    A: ArrayLike, gamma: ArrayLike, theta: ArrayLike, dtheta: ArrayLike
) -> NDArray[np.float64]:
    """Minimum shooting distance for an object rotating out of the image plane (eq. 2.6).

    Parameters
    ----------
    A : array_like
        Object length (mm), > 0.
    gamma : array_like
        Relative reading error of the image length of the upright object, 0 < gamma < cos(theta).
    theta : array_like
        Initial rotation out of the image plane (rad), >= 0.
    dtheta : array_like
        Further rotation range (rad), > 0, with theta + dtheta <= pi/2.

    Returns
    -------
    ndarray
        ``L_min = (cos(theta) - gamma) / gamma * A * (sin(theta + dtheta) - sin(theta))``, in the unit
        of ``A``. Broadcasts over all inputs.

    Examples
    --------
    >>> round(float(min_shooting_distance_rotation(1.0, 0.01, 0.0, np.radians(30))), 2)
    49.5
    """
    A, gamma, theta, dtheta = (np.asarray(v, dtype=float) for v in (A, gamma, theta, dtheta))
    if np.any(A <= 0):
        raise InvalidArgument("A (object length) must be > 0")
    if np.any(theta < 0) or np.any(dtheta <= 0) or np.any(theta + dtheta > np.pi / 2 + 1e-12):
        raise InvalidArgument(
            "need theta >= 0, dtheta > 0 and theta + dtheta <= pi/2 (angles in rad); outside this "
            "range eq. 2.4 is not monotone and eq. 2.6 does not apply"
        )
    if np.any((gamma <= 0) | (gamma >= np.cos(theta))):
        raise InvalidArgument("gamma must satisfy 0 < gamma < cos(theta); e.g. gamma = 0.01")
    return (np.cos(theta) - gamma) / gamma * A * (np.sin(theta + dtheta) - np.sin(theta))


@dataclass(frozen=True)
class ParallelChainResult:
    """Result of :func:`reconstruct_chain_parallel`.

    Attributes
    ----------
    points : ndarray, shape (..., N, 3)
        Marker positions (mm) of markers 1..N in the frame of marker 0.
    candidates : ndarray, shape (..., N, 2)
        ``|Z_n - Z_{n-1}|`` magnitudes are symmetric, so this holds the two candidate depth
        increments (+, -) per link (mm).
    signs : ndarray of int, shape (..., N)
        The signs used.
    flags : dict
        ``"segment_in_image_plane"``: boolean array (..., N) of clamped radicands.
    """

    points: NDArray[np.float64]
    candidates: NDArray[np.float64]
    signs: NDArray[np.int_]
    flags: dict = field(default_factory=dict)


def reconstruct_chain_parallel(
    image_xy: ArrayLike,
    lengths: ArrayLike,
    magnification: float,
    signs: ArrayLike | None = None,
    resolver: SignResolver | None = None,
    tol_radicand: float = 1e-3,
) -> ParallelChainResult:
    """Reconstruct a marker chain from one image under parallel projection (eqs 2.7, 2.10, 2.11).

    Parameters
    ----------
    image_xy : array_like, shape (..., N, 2)
        Image coordinates (mm) of markers 1..N relative to the image of marker 0. Leading axes are
        frames (vectorised).
    lengths : array_like, shape (N,) or (..., N)
        Known link lengths D_n (mm); link n joins markers n-1 and n.
    magnification : float
        ``m = L / ell`` (object distance over image distance), dimensionless.
    signs : array_like of {+1, -1, 0}, shape (N,) or (..., N), optional
        ``s_n = +1`` when marker n lies further toward +Z than marker n-1. The sign cannot be read
        from the image; 0 (or omitted) means "unknown" and needs ``resolver``.
    resolver : callable, optional
        ``resolver(frame, link, candidates) -> +1 | -1`` for links whose sign is unknown.
    tol_radicand : float
        Negative radicands down to ``-tol_radicand * D_n**2`` are clamped to 0 and flagged.

    Returns
    -------
    ParallelChainResult

    Raises
    ------
    AmbiguousSign
        A sign is unknown and no resolver is given (names frame and marker).
    InconsistentLength
        The projected segment is longer than its link (names frame and marker).

    Examples
    --------
    >>> r = reconstruct_chain_parallel([[0.3, 0.4]], [1.0], magnification=1.0, signs=[1])
    >>> np.round(r.points, 6).tolist()
    [[0.3, 0.4, 0.866025]]
    """
    xy = np.asarray(image_xy, dtype=float)
    if xy.ndim < 2 or xy.shape[-1] != 2:
        raise InvalidArgument(f"image_xy must have shape (..., N, 2); got {xy.shape}")
    n = xy.shape[-2]
    D = np.broadcast_to(np.asarray(lengths, dtype=float), xy.shape[:-1])
    if np.any(D <= 0):
        raise InvalidArgument("link lengths must be > 0 (mm)")
    XY = magnification * xy  # (2.7)
    prev = np.concatenate([np.zeros_like(XY[..., :1, :]), XY[..., :-1, :]], axis=-2)
    r = D**2 - np.sum((XY - prev) ** 2, axis=-1)
    flat_r = r.reshape(-1, n)
    flat_D = D.reshape(-1, n)
    bad = flat_r < -tol_radicand * flat_D**2
    if np.any(bad):
        f, i = np.argwhere(bad)[0]
        raise InconsistentLength(
            f"frame {f}, marker {i + 1}: projected link length "
            f"{np.sqrt(flat_D[f, i]**2 - flat_r[f, i]):.4g} mm exceeds the link length {flat_D[f, i]:.4g} mm; "
            "check the link length, the magnification and the image coordinates"
        )
    clamped = r < 0
    dz = np.sqrt(np.maximum(r, 0.0))
    cand = np.stack([dz, -dz], axis=-1)

    s = np.zeros(xy.shape[:-1], dtype=int) if signs is None else np.broadcast_to(
        np.asarray(signs), xy.shape[:-1]
    ).astype(int).copy()
    if np.any((s != 0) & (np.abs(s) != 1)):
        raise InvalidArgument("signs must be +1, -1 or 0 (unknown)")
    missing = np.argwhere(s.reshape(-1, n) == 0)
    if len(missing) and resolver is None:
        f, i = missing[0]
        raise AmbiguousSign(
            f"frame {f}, marker {i + 1}: the depth sign cannot be obtained from a parallel projection; "
            "pass signs=[...] or a resolver(frame, link, candidates) callable"
        )
    flat_s = s.reshape(-1, n)
    if len(missing):
        # Sequential only over links with unknown sign: the resolver sees absolute candidates.
        for f in np.unique(missing[:, 0]):
            for i in range(n):
                if flat_s[f, i] != 0:
                    continue
                zprev = np.sum(flat_s[f, :i] * dz.reshape(-1, n)[f, :i])
                xyi = XY.reshape(-1, n, 2)[f, i]
                pts = np.array([[*xyi, zprev + dz.reshape(-1, n)[f, i]], [*xyi, zprev - dz.reshape(-1, n)[f, i]]])
                choice = int(resolver(int(f), i + 1, pts))
                if choice not in (1, -1):
                    raise AmbiguousSign(f"frame {f}, marker {i + 1}: resolver returned {choice!r}, not +1/-1")
                flat_s[f, i] = choice
        s = flat_s.reshape(s.shape)
    Z = np.cumsum(s * dz, axis=-1)  # (2.10), (2.11)
    pts = np.concatenate([XY, Z[..., None]], axis=-1)
    return ParallelChainResult(pts, cand, s, {"segment_in_image_plane": clamped})
