"""Analytic RSSR spatial four-bar (thesis §3.6.1, eqs 3.39-3.44, Appendix 3 A.1-A.19).

:func:`rssr_state` gives the joint positions and the output angle, velocity and acceleration
for given input angles; :func:`rssr_angles_from_markers` measures input and output angles from
the spherical-joint markers S_A, S_C, so that measured kinematics can be compared with the model.
:data:`THESIS_RSSR` is the spec's synthetic completion of the thesis mechanism (§6.5).

Units: mm, rad, s; right-handed world frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import CannotAssemble, DegenerateLinkage, RSSRError, SingularFrame, ToggleSingularity

__all__ = ["RSSRParams", "RSSRState", "THESIS_RSSR", "rssr_state", "rssr_angles_from_markers", "rotate"]

FloatArray = NDArray[np.float64]


def _unit(v: ArrayLike) -> FloatArray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _dot(x: FloatArray, y: FloatArray) -> FloatArray:
    return np.einsum("...i,...i", x, y)


def rotate(v: ArrayLike, axis: ArrayLike, angle: ArrayLike) -> FloatArray:
    """Rotate ``v`` by ``angle`` (rad, right-hand rule) about the unit ``axis`` (Rodrigues).

    Examples
    --------
    >>> rotate([1.0, 0, 0], [0.0, 0, 1], np.pi / 2).round(12).tolist()
    [0.0, 1.0, 0.0]
    """
    v = np.asarray(v, dtype=float)
    k = _unit(axis)
    th = np.asarray(angle, dtype=float)[..., None]
    return v * np.cos(th) + np.cross(k, v) * np.sin(th) + k * _dot(k, v)[..., None] * (1 - np.cos(th))


@dataclass(frozen=True)
class RSSRParams:
    """Geometry of an RSSR linkage (mm); axes need not be unit vectors.

    Attributes
    ----------
    O_A : input pivot (on the input axis ``e``).
    e : input axis direction.
    a0 : crank vector O_A -> S_A at theta = 0 (perpendicular to ``e`` for a plain crank).
    d : vector O_A -> O_C.
    f : output axis direction.
    b, c : coupler and output-crank lengths.
    c1 : ``c_hat . f_hat`` (0 for a crank perpendicular to its axis).
    branch : +1 or -1, the assembly branch (sign of the root in (3.39)).
    """

    O_A: tuple[float, float, float] = (0.0, 0.0, 0.0)
    e: tuple[float, float, float] = (0.0, 0.0, 1.0)
    a0: tuple[float, float, float] = (61.0, 0.0, 0.0)
    d: tuple[float, float, float] = (-191.5, -73.0, -183.0)
    f: tuple[float, float, float] = (-0.978498, 0.0, 0.206555)
    b: float = 272.0
    c: float = 116.0
    c1: float = 0.0
    branch: int = 1


#: The spec's synthetic completion of the thesis RSSR (kinematics.md §6.5); theta_dot = 0.58 rad/s.
THESIS_RSSR = RSSRParams()
#: Input crank speed of the thesis experiment (rad/s).
THESIS_THETA_DOT = 0.58


@dataclass(frozen=True)
class RSSRState:
    """Kinematic state of the RSSR linkage, arrays over the input angles.

    Attributes
    ----------
    theta : input angle (rad).
    a, b, c : crank, coupler and output-crank vectors (mm), shape (..., 3).
    S_A, S_C : spherical-joint positions (mm).
    phi : signed output angle from the theta = 0 position about ``f`` (rad, in (-pi, pi]).
    phi_dot, phi_ddot : rad/s, rad/s² (3.42)-(3.44).
    branch_point : True where the discriminant of (3.39) is (numerically) zero.
    """

    theta: FloatArray
    a: FloatArray
    b: FloatArray
    c: FloatArray
    S_A: FloatArray
    S_C: FloatArray
    phi: FloatArray
    phi_dot: FloatArray
    phi_ddot: FloatArray
    branch_point: NDArray[np.bool_]


def _c_hat(theta: FloatArray, p: RSSRParams, branch: int) -> tuple[FloatArray, FloatArray, NDArray[np.bool_]]:
    e, f = _unit(p.e), _unit(p.f)
    a = rotate(np.asarray(p.a0, float), e, theta)
    dv = np.asarray(p.d, float) - a
    u = np.linalg.norm(dv, axis=-1)
    if np.any(u == 0):
        k = int(np.flatnonzero(np.ravel(u == 0))[0])
        raise DegenerateLinkage(f"u = |d - a| = 0 at theta = {np.ravel(theta)[k]:.6g} rad; check d and a0")
    uh = dv / u[..., None]
    c2 = (p.b**2 - p.c**2 - u**2) / (2 * p.c * u)  # (A.9)
    if np.any(np.abs(c2) > 1):
        k = int(np.flatnonzero(np.ravel(np.abs(c2) > 1))[0])
        raise CannotAssemble(
            f"linkage cannot close at theta = {np.ravel(theta)[k]:.6g} rad (|c2| > 1); check lengths b, c"
        )
    kk = _dot(np.broadcast_to(f, uh.shape), uh)
    if np.any(1 - kk**2 < 1e-12):
        k = int(np.flatnonzero(np.ravel(1 - kk**2 < 1e-12))[0])
        raise SingularFrame(f"u is parallel to the output axis f at theta = {np.ravel(theta)[k]:.6g} rad")
    c1 = p.c1
    disc = 1 - kk**2 - c1**2 - c2**2 + 2 * c1 * c2 * kk
    if np.any(disc < -1e-12):
        k = int(np.flatnonzero(np.ravel(disc < -1e-12))[0])
        raise CannotAssemble(
            f"negative discriminant at theta = {np.ravel(theta)[k]:.6g} rad: the output crank cannot "
            "reach the coupler; check the geometry"
        )
    bp = np.abs(disc) <= 1e-12
    s = np.sqrt(1 - kk**2)
    mu = np.cross(f, uh) / s[..., None]
    lam = np.cross(mu, uh)
    ch = ((c2 * kk - c1)[..., None] * lam + branch * np.sqrt(np.maximum(disc, 0))[..., None] * mu) / s[
        ..., None
    ] + c2[..., None] * uh  # (3.39)
    return a, ch, bp


def rssr_state(
    theta: ArrayLike,
    theta_dot: ArrayLike = THESIS_THETA_DOT,
    theta_ddot: ArrayLike = 0.0,
    params: RSSRParams = THESIS_RSSR,
    branch: int | None = None,
) -> RSSRState:
    """Positions, output angle, velocity and acceleration of the RSSR linkage (§6.4).

    Parameters
    ----------
    theta : array_like
        Input crank angle(s) (rad) about ``e`` from ``a0``.
    theta_dot, theta_ddot : array_like
        Input angular velocity (rad/s) and acceleration (rad/s²; the thesis has 0).
    params : RSSRParams
        Geometry (default: :data:`THESIS_RSSR`).
    branch : {+1, -1}, optional
        Assembly branch; default ``params.branch``. Kept fixed along the motion.

    Returns
    -------
    RSSRState

    Raises
    ------
    DegenerateLinkage, CannotAssemble, SingularFrame, ToggleSingularity
        Naming the input angle where the linkage fails.

    Examples
    --------
    >>> s = rssr_state(0.0)
    >>> s.S_C.round(3).tolist(), round(float(s.phi_dot), 6), round(float(s.phi_ddot), 6)
    ([-169.63, -120.373, -79.398], 0.227955, -0.219261)
    """
    p = params
    br = p.branch if branch is None else branch
    if br not in (1, -1):
        raise RSSRError(f"branch must be +1 or -1, got {br}")
    th = np.asarray(theta, dtype=float)
    e, f = _unit(p.e), _unit(p.f)
    a, ch, bp = _c_hat(th, p, br)
    _, ch0, _ = _c_hat(np.asarray(0.0), p, br)
    c = p.c * ch
    dvec = np.asarray(p.d, float)
    b = c + dvec - a  # (A.5)
    nb = np.linalg.norm(b, axis=-1)
    if np.any(np.abs(nb - p.b) > 1e-9 * p.b):
        raise CannotAssemble(f"loop closure failed: |b| differs from {p.b} mm; check c1 and the axes")
    den = _dot(np.broadcast_to(f, c.shape), np.cross(c, b))
    tog = np.abs(den) <= 1e-9 * p.c * p.b
    if np.any(tog):
        k = int(np.flatnonzero(np.ravel(tog))[0])
        raise ToggleSingularity(
            f"toggle position at theta = {np.ravel(th)[k]:.6g} rad: f . (c x b) = 0, output velocity undefined"
        )
    td = np.asarray(theta_dot, dtype=float)
    tdd = np.asarray(theta_ddot, dtype=float)
    eab = _dot(np.broadcast_to(e, a.shape), np.cross(a, b))
    phid = eab / den * td  # (3.42)
    exa = np.cross(e, a)
    fxc = np.cross(f, c)
    bw2 = _dot(exa, exa) * td**2 - 2 * td * phid * _dot(exa, fxc) + _dot(fxc, fxc) * phid**2  # (3.44)
    num = (
        (_dot(a, np.broadcast_to(e, a.shape)) * _dot(b, np.broadcast_to(e, b.shape)) - _dot(a, b)) * td**2
        - (_dot(b, np.broadcast_to(f, b.shape)) * _dot(c, np.broadcast_to(f, c.shape)) - _dot(b, c)) * phid**2
        - bw2
        + tdd * eab
    )
    phidd = num / den  # (3.43)
    # signed output angle about f, both vectors projected on the plane normal to f
    pc0 = ch0 - _dot(ch0, f) * f
    pc = ch - _dot(ch, np.broadcast_to(f, ch.shape))[..., None] * f
    phi = np.arctan2(_dot(np.cross(np.broadcast_to(pc0, pc.shape), pc), np.broadcast_to(f, pc.shape)),
                     _dot(np.broadcast_to(pc0, pc.shape), pc))
    O_A = np.asarray(p.O_A, float)
    return RSSRState(th, a, b, c, O_A + a, O_A + dvec + c, phi, phid, phidd, bp)


def rssr_angles_from_markers(
    S_A: ArrayLike, S_C: ArrayLike, params: RSSRParams = THESIS_RSSR, unwrap: bool = True
) -> tuple[FloatArray, FloatArray]:
    """Measured input and output angles from the spherical-joint markers.

    ``theta`` is the angle of ``S_A - O_A`` about ``e`` from ``a0``; ``phi`` the angle of
    ``S_C - O_C`` about ``f`` from the model's theta = 0 output crank; both vectors are projected
    on the plane normal to their axis, so marker noise along the axis is ignored.

    Parameters
    ----------
    S_A, S_C : array_like, shape (T, 3)
        Marker positions (mm), world frame of the linkage; NaN where missing.
    params : RSSRParams
        Pivots and axes (known from the set-up).
    unwrap : bool
        Unwrap along axis 0 (continuous angles over several revolutions; NaN frames are skipped).

    Returns
    -------
    theta, phi : ndarray, shape (T,)
        rad.

    Examples
    --------
    >>> s = rssr_state(np.linspace(0.0, 6.0, 50))
    >>> th, ph = rssr_angles_from_markers(s.S_A, s.S_C)
    >>> bool(np.allclose(th, np.linspace(0, 6, 50)) and np.allclose(ph, s.phi))
    True
    """
    p = params
    e, f = _unit(p.e), _unit(p.f)
    O_A = np.asarray(p.O_A, float)
    O_C = O_A + np.asarray(p.d, float)
    _, ch0, _ = _c_hat(np.asarray(0.0), p, p.branch)

    def angle(v: FloatArray, ref: FloatArray, ax: FloatArray) -> FloatArray:
        v = v - _dot(v, np.broadcast_to(ax, v.shape))[..., None] * ax
        r = ref - _dot(ref, ax) * ax
        rb = np.broadcast_to(r, v.shape)
        return np.arctan2(_dot(np.cross(rb, v), np.broadcast_to(ax, v.shape)), _dot(rb, v))

    th = angle(np.asarray(S_A, float) - O_A, np.asarray(p.a0, float), e)
    ph = angle(np.asarray(S_C, float) - O_C, ch0, f)
    if unwrap:
        for arr in (th, ph):
            ok = np.isfinite(arr)
            arr[ok] = np.unwrap(arr[ok])
    return th, ph
