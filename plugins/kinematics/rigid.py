"""Rigid-body kinematics: pose from markers, angular velocity, body frame, angular momentum.

* :func:`kabsch` -- least-squares pose per frame from >= 3 visible markers (SVD, vectorised
  over frames; NaN when fewer than 3 non-collinear markers are visible).
* :func:`rigid_body_motion` -- pose + angular velocity (world frame) of a marker cluster.
* :func:`angular_velocity_two_vectors` -- thesis eqs (3.49)-(3.51) and the least-squares variant.
* :func:`body_frame` -- rotation matrix T of (3.52)-(3.53).
* :func:`angular_momentum` -- H_G in the world frame, (3.45)-(3.48).

Conventions: right-handed world frame, positions in mm, time in s, angles in rad. A rotation
``R`` maps body coordinates to world coordinates (``p_world = R @ q_body + origin``); the
thesis's ``T`` (rows = body axes in world components) is ``R.T``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .derivatives import derivatives
from .errors import (
    DegenerateAngularVelocity,
    DegenerateMarkerSet,
    InsufficientSamples,
    ParallelBodyVectors,
    first_index,
)
from .filters import check_time

__all__ = [
    "RigidBodyMotion",
    "kabsch",
    "rigid_body_motion",
    "omega_from_rotations",
    "angular_velocity_two_vectors",
    "body_frame",
    "angular_momentum",
    "skew",
    "vee",
]

FloatArray = NDArray[np.float64]


def skew(w: ArrayLike) -> FloatArray:
    """Cross-product matrix ``[w]x`` (..., 3, 3) of vectors (..., 3).

    Examples
    --------
    >>> skew([1.0, 2.0, 3.0]) @ np.array([0.0, 0.0, 1.0])
    array([ 2., -1.,  0.])
    """
    w = np.asarray(w, dtype=float)
    z = np.zeros(w.shape[:-1])
    x, y, q = w[..., 0], w[..., 1], w[..., 2]
    return np.stack(
        [np.stack([z, -q, y], -1), np.stack([q, z, -x], -1), np.stack([-y, x, z], -1)], -2
    )


def vee(m: ArrayLike) -> FloatArray:
    """Vector of the skew-symmetric part of (..., 3, 3) matrices (inverse of :func:`skew`)."""
    m = np.asarray(m, dtype=float)
    return 0.5 * np.stack(
        [m[..., 2, 1] - m[..., 1, 2], m[..., 0, 2] - m[..., 2, 0], m[..., 1, 0] - m[..., 0, 1]], -1
    )


def kabsch(
    reference: ArrayLike, markers: ArrayLike, collinear_tol: float = 1e-6
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.int_]]:
    """Least-squares rigid pose per frame: ``markers[t] ≈ R[t] @ reference + origin[t]``.

    Only the markers visible (finite) in a frame enter that frame's fit.

    Parameters
    ----------
    reference : array_like, shape (M, 3)
        Body-fixed marker coordinates (mm).
    markers : array_like, shape (T, M, 3) or (M, 3)
        Measured world positions (mm), NaN where missing.
    collinear_tol : float
        A frame whose visible markers are collinear (second singular value of the covariance below
        ``collinear_tol`` times the first) has no defined pose.

    Returns
    -------
    R : ndarray, shape (T, 3, 3)
        Proper rotations (det = +1), body to world; NaN for frames with < 3 usable markers.
    origin : ndarray, shape (T, 3)
        World position (mm) of the reference origin.
    rms : ndarray, shape (T,)
        Root-mean-square fit residual (mm) over the visible markers.
    n_visible : ndarray of int, shape (T,)

    Examples
    --------
    >>> q = np.array([[0.0, 0, 0], [100, 0, 0], [0, 50, 0], [0, 0, 30]])
    >>> Rz = np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]])
    >>> R, o, rms, n = kabsch(q, q @ Rz.T + [10.0, 20, 30])
    >>> bool(np.allclose(R[0], Rz)), o[0].round(6).tolist()
    (True, [10.0, 20.0, 30.0])
    """
    q = np.asarray(reference, dtype=float)
    p = np.asarray(markers, dtype=float)
    if p.ndim == 2:
        p = p[None]
    if q.ndim != 2 or q.shape[1] != 3 or p.shape[1:] != q.shape:
        raise DegenerateMarkerSet(
            f"reference {q.shape} and markers {p.shape} do not match: expected (M, 3) and (T, M, 3)"
        )
    w = np.all(np.isfinite(p), axis=-1).astype(float)  # (T, M)
    n = w.sum(1)
    p0 = np.where(w[..., None] > 0, p, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        pc = np.einsum("tm,tmi->ti", w, p0) / n[:, None]
        qc = (w @ q) / n[:, None]
    dq = q[None] - qc[:, None]
    dp = p0 - pc[:, None]
    H = np.einsum("tm,tmi,tmj->tij", w, dq, dp)
    ok = n >= 3
    H[~ok] = np.eye(3)
    U, S, Vt = np.linalg.svd(H)
    ok &= S[:, 1] > collinear_tol * np.maximum(S[:, 0], 1e-300)
    V = np.swapaxes(Vt, -1, -2)
    d = np.sign(np.linalg.det(V @ np.swapaxes(U, -1, -2)))
    D = np.zeros_like(H)
    D[:, 0, 0] = 1.0
    D[:, 1, 1] = 1.0
    D[:, 2, 2] = np.where(d == 0, 1.0, d)
    R = V @ D @ np.swapaxes(U, -1, -2)
    origin = pc - np.einsum("tij,tj->ti", R, qc)
    resid = p0 - (np.einsum("tij,mj->tmi", R, q) + origin[:, None])
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt(np.einsum("tm,tmi->t", w, resid**2) / n)
    R[~ok] = np.nan
    origin[~ok] = np.nan
    rms[~ok] = np.nan
    return R, origin, rms, n.astype(int)


def _auto_reference(markers: FloatArray) -> FloatArray:
    full = np.flatnonzero(np.all(np.isfinite(markers), axis=(1, 2)))
    if full.size == 0:
        raise DegenerateMarkerSet(
            "no frame shows all markers, so the body-fixed marker layout is unknown; pass "
            "reference=(M, 3) body coordinates (mm) to rigid_body_motion"
        )
    ref = markers[full[0]] - markers[full[0]].mean(0)
    R, o, _, _ = kabsch(ref, markers[full])
    good = np.all(np.isfinite(R), axis=(1, 2))
    if not np.any(good):
        raise DegenerateMarkerSet("the markers are collinear in every complete frame; no rigid body")
    back = np.einsum("tji,tmj->tmi", R[good], markers[full][good] - o[good][:, None])
    mean = back.mean(0)
    # express in the axes of the first complete frame, centred at the centroid
    R0, _, _, _ = kabsch(mean, markers[full[0]])
    return (mean - mean.mean(0)) @ R0[0].T


def omega_from_rotations(
    t: ArrayLike, R: ArrayLike, method: str = "smoothing_spline", **params: object
) -> FloatArray:
    """World-frame angular velocity from sampled rotation matrices: ``[w]x = dR/dt R^T``.

    The nine matrix elements are differentiated with :func:`derivatives` (``method``, ``params``);
    the skew-symmetric part of ``dR/dt R^T`` gives omega (rad/s). NaN frames split the series.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 101)
    >>> c, s = np.cos(2 * t), np.sin(2 * t)
    >>> R = np.zeros((101, 3, 3)); R[:, 0, 0] = c; R[:, 0, 1] = -s; R[:, 1, 0] = s; R[:, 1, 1] = c
    >>> R[:, 2, 2] = 1.0
    >>> w = omega_from_rotations(t, R, lam=0.0)
    >>> bool(np.allclose(w[10:-10], [0, 0, 2], atol=1e-6))
    True
    """
    RR = np.asarray(R, dtype=float)
    Rs, Rd, _ = derivatives(t, RR, method=method, **params)
    return vee(Rd @ np.swapaxes(Rs, -1, -2))


@dataclass(frozen=True)
class RigidBodyMotion:
    """Pose and angular velocity of a rigid marker cluster.

    Attributes
    ----------
    t : ndarray, shape (T,)
        Times (s).
    R : ndarray, shape (T, 3, 3)
        Body-to-world rotation (NaN when < 3 markers are visible).
    origin : ndarray, shape (T, 3)
        World position (mm) of the body origin (centroid of ``reference``).
    omega : ndarray, shape (T, 3)
        Angular velocity in the world frame (rad/s).
    rms : ndarray, shape (T,)
        Per-frame rigid-fit residual (mm).
    n_visible : ndarray, shape (T,)
        Markers used per frame.
    reference : ndarray, shape (M, 3)
        Body-fixed marker coordinates (mm) in the body frame.
    """

    t: FloatArray
    R: FloatArray
    origin: FloatArray
    omega: FloatArray
    rms: FloatArray
    n_visible: NDArray[np.int_]
    reference: FloatArray


def rigid_body_motion(
    t: ArrayLike,
    markers: ArrayLike,
    reference: ArrayLike | None = None,
    method: str = "smoothing_spline",
    **params: object,
) -> RigidBodyMotion:
    """Pose and world-frame angular velocity of a rigid cluster of >= 3 markers with gaps.

    Each frame is fitted (:func:`kabsch`) with whichever markers are visible; frames with fewer
    than 3 (or collinear) visible markers get NaN. Angular velocity comes from
    :func:`omega_from_rotations` (``method``/``params`` as in :func:`derivatives`).

    Parameters
    ----------
    t : array_like, shape (T,)
        Frame times (s).
    markers : array_like, shape (T, M, 3)
        Marker positions (mm), M >= 3, NaN where missing.
    reference : array_like, shape (M, 3), optional
        Body-fixed marker coordinates (mm). Default: the layout averaged over the frames in which
        all markers are visible, centred on its centroid, axes = world axes at the first such
        frame (so ``R`` is the rotation relative to that frame).
    method, **params
        Differentiation method for omega (see :func:`derivatives`).

    Returns
    -------
    RigidBodyMotion

    Raises
    ------
    DegenerateMarkerSet
        Fewer than 3 markers, or no complete frame and no ``reference``.

    Examples
    --------
    >>> t = np.linspace(0.0, 1.0, 51)
    >>> q = np.array([[0.0, 0, 0], [100, 0, 0], [0, 60, 0], [0, 0, 40]])
    >>> ang = 1.5 * t
    >>> Rz = np.zeros((51, 3, 3)); Rz[:, 0, 0] = np.cos(ang); Rz[:, 0, 1] = -np.sin(ang)
    >>> Rz[:, 1, 0] = np.sin(ang); Rz[:, 1, 1] = np.cos(ang); Rz[:, 2, 2] = 1
    >>> m = np.einsum("tij,mj->tmi", Rz, q); m[10, 2] = np.nan
    >>> rb = rigid_body_motion(t, m, lam=0.0)
    >>> bool(np.allclose(rb.omega[5:-5], [0, 0, 1.5], atol=1e-5))
    True
    """
    p = np.asarray(markers, dtype=float)
    if p.ndim != 3 or p.shape[2] != 3 or p.shape[1] < 3:
        raise DegenerateMarkerSet(
            f"markers must have shape (T, M>=3, 3), got {p.shape}; a rigid body needs >= 3 markers"
        )
    tt = check_time(t, p.shape[0])
    if reference is None:
        ref = _auto_reference(p)
    else:
        ref = np.asarray(reference, dtype=float)
        if ref.shape != p.shape[1:]:
            raise DegenerateMarkerSet(f"reference has shape {ref.shape}, expected {p.shape[1:]}")
    R, origin, rms, n = kabsch(ref, p)
    omega = omega_from_rotations(tt, R, method=method, **params)
    return RigidBodyMotion(tt, R, origin, omega, rms, n, ref)


def angular_velocity_two_vectors(
    a: ArrayLike,
    b: ArrayLike,
    da: ArrayLike,
    db: ArrayLike,
    mode: str = "thesis",
    tol: float = 1e-3,
    on_degenerate: str = "raise",
) -> tuple[FloatArray, FloatArray]:
    """Angular velocity from two body-fixed vectors and their derivatives (eqs 3.49-3.51).

    Thesis mode: ``omega = (c1 x c2) / (b . c1)`` with ``c1 = da/dt``, ``c2 = db/dt``. Robust mode:
    the least-squares solution of ``c1 = omega x a``, ``c2 = omega x b``.

    Parameters
    ----------
    a, b : array_like, shape (..., 3)
        Body-fixed vectors in the world frame (any length unit, e.g. mm).
    da, db : array_like, shape (..., 3)
        Their time derivatives (unit/s).
    mode : {"thesis", "robust"}
    tol : float
        Thesis mode: ``|b . c1| <= tol |b| |c1|`` is degenerate (omega in the plane of a, b).
    on_degenerate : {"raise", "nan"}
        Raise :class:`DegenerateAngularVelocity` (naming the first frame) or return NaN there.

    Returns
    -------
    omega : ndarray, shape (..., 3)
        rad/s, world frame.
    residuals : ndarray, shape (..., 3)
        Normalised rigidity residuals (3.50): ``a.c1/(|a||c1|)``, ``b.c2/(|b||c2|)``,
        ``(a.c2 + b.c1)/(|a||c2| + |b||c1|)``; zero for error-free data.

    Raises
    ------
    ParallelBodyVectors
        If ``|a x b| < 1e-6 |a||b|``.

    Examples
    --------
    >>> w = np.array([0.3, -1.0, 2.0]); a = np.array([1.0, 0, 0]); b = np.array([0.0, 1, 0])
    >>> om, r = angular_velocity_two_vectors(a, b, np.cross(w, a), np.cross(w, b))
    >>> om.round(12).tolist()
    [0.3, -1.0, 2.0]
    """
    a, b, c1, c2 = (np.asarray(v, dtype=float) for v in (a, b, da, db))
    na, nb = np.linalg.norm(a, axis=-1), np.linalg.norm(b, axis=-1)
    axb = np.cross(a, b)
    par = np.linalg.norm(axb, axis=-1) < 1e-6 * na * nb
    if np.any(par):
        k = first_index(par)
        raise ParallelBodyVectors(
            f"body vectors a and b are parallel at frame {k}; choose two marker differences "
            "that span a plane"
        )
    nc1, nc2 = np.linalg.norm(c1, axis=-1), np.linalg.norm(c2, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        res = np.stack(
            [
                np.einsum("...i,...i", a, c1) / (na * nc1),
                np.einsum("...i,...i", b, c2) / (nb * nc2),
                (np.einsum("...i,...i", a, c2) + np.einsum("...i,...i", b, c1))
                / (na * nc2 + nb * nc1),
            ],
            -1,
        )
    if mode == "thesis":
        den = np.einsum("...i,...i", b, c1)
        deg = np.abs(den) <= tol * nb * nc1
        if np.any(deg) and on_degenerate == "raise":
            k = first_index(deg)
            raise DegenerateAngularVelocity(
                f"b . c1 ~ 0 at frame {k}: omega lies in the plane of a and b (or is zero); use "
                "mode='robust' or other body vectors"
            )
        with np.errstate(invalid="ignore", divide="ignore"):
            om = np.cross(c1, c2) / den[..., None]
        om = np.where(deg[..., None], np.nan, om)
    elif mode == "robust":
        eye = np.eye(3)
        M = (na**2)[..., None, None] * eye - a[..., :, None] * a[..., None, :]
        M = M + (nb**2)[..., None, None] * eye - b[..., :, None] * b[..., None, :]
        rhs = np.cross(a, c1) + np.cross(b, c2)
        om = np.linalg.solve(M, rhs[..., None])[..., 0]
    else:
        raise InsufficientSamples(f"mode must be 'thesis' or 'robust', got {mode!r}")
    return om, res


def body_frame(a: ArrayLike, b: ArrayLike) -> FloatArray:
    """Rotation matrix T of (3.52)-(3.53): rows ``i = a/|a|``, ``j = unit(a x b)``, ``k = i x j``.

    Parameters
    ----------
    a, b : array_like, shape (..., 3)
        Non-parallel body-fixed vectors (world components).

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Orthonormal T (world -> body components: ``v_body = T @ v_world``).

    Raises
    ------
    ParallelBodyVectors

    Examples
    --------
    >>> body_frame([2.0, 0, 0], [0.0, 3, 0]).tolist()
    [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]]
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    axb = np.cross(a, b)
    na, nb, nab = (np.linalg.norm(v, axis=-1) for v in (a, b, axb))
    if np.any(nab < 1e-6 * na * nb):
        raise ParallelBodyVectors(
            "a and b are parallel in some frame; the body frame (3.52) is undefined - choose "
            "other marker pairs"
        )
    i = a / na[..., None]
    j = axb / nab[..., None]
    k = np.cross(i, j)
    return np.stack([i, j, k], -2)


def angular_momentum(T: ArrayLike, inertia: ArrayLike, omega: ArrayLike) -> FloatArray:
    """Angular momentum about the centre of mass in the world frame, (3.48): ``T^T I T omega``.

    Parameters
    ----------
    T : array_like, shape (..., 3, 3)
        Rows = body axes in world components (:func:`body_frame`, or ``R.T`` of a
        :class:`RigidBodyMotion`).
    inertia : array_like, shape (3, 3) or (3,)
        Inertia tensor about G in the body axes (kg·m²); a (3,) input is a diagonal.
    omega : array_like, shape (..., 3)
        World-frame angular velocity (rad/s).

    Returns
    -------
    ndarray, shape (..., 3)
        H_G in world components (kg·m²/s).

    Examples
    --------
    >>> angular_momentum(np.eye(3), [1.0, 2.0, 3.0], [1.0, 1.0, 1.0]).tolist()
    [1.0, 2.0, 3.0]
    """
    I = np.asarray(inertia, dtype=float)
    if I.shape == (3,):
        I = np.diag(I)
    TT = np.asarray(T, dtype=float)
    w_body = np.einsum("...ij,...j->...i", TT, np.asarray(omega, dtype=float))  # (3.46)
    h_body = np.einsum("ij,...j->...i", I, w_body)  # (3.45)
    return np.einsum("...ji,...j->...i", TT, h_body)  # (3.48)
