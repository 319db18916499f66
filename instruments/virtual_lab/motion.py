"""The virtual lab's own motion models: the exact motions its scenes play.

Written here rather than taken from the kinematics plugin: the scenes' analytic quantities are the
truth that plugin is validated against, so a bug shared by both would cancel out. Each model is
formulated differently from the plugin's (``tests/instruments/virtual_lab/test_own_models.py`` cross-checks
the two):

* :func:`rotate`: Rodrigues' rotation of vectors about an axis.
* :func:`rssr_motion`: the RSSR spatial four-bar (``kinematics.md`` §6) solved as a circle meeting
  a sphere (the output crank's circle about its axis at the coupler's length from the input
  crank), its output rates from the time derivatives of that distance constraint (the plugin uses
  the thesis's closed forms 3.39-3.44).
* :func:`torque_free_rotation`: Euler's equations with the attitude as a unit quaternion (the
  plugin integrates the rotation matrix).
* :func:`box_inertia`, :func:`box_vertices`: the uniform box of the thrown-box experiment.

Units: mm, s, rad; inertia kg·m².
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

__all__ = ["RSSRGeometry", "RSSRMotion", "THESIS_RSSR", "THESIS_THETA_DOT", "box_inertia", "box_vertices",
           "rotate", "rssr_motion", "torque_free_rotation"]

FloatArray = NDArray[np.float64]


def _unit(v: ArrayLike) -> FloatArray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _dot(x: FloatArray, y: FloatArray) -> FloatArray:
    return np.sum(x * y, axis=-1)


def rotate(v: ArrayLike, axis: ArrayLike, angle: ArrayLike) -> FloatArray:
    """Rotate ``v`` by ``angle`` (rad, right-hand rule) about ``axis`` (Rodrigues' formula).

    Examples
    --------
    >>> rotate([1.0, 0.0, 0.0], [0.0, 0.0, 2.0], np.pi / 2).round(12).tolist()
    [0.0, 1.0, 0.0]
    """
    v = np.asarray(v, dtype=float)
    k = _unit(axis)
    th = np.asarray(angle, dtype=float)[..., None]
    cos, sin = np.cos(th), np.sin(th)
    return cos * v + sin * np.cross(k, v) + (1.0 - cos) * _dot(k, v)[..., None] * k


# ---------------------------------------------------------------------------------------------- RSSR
@dataclass(frozen=True)
class RSSRGeometry:
    """An RSSR linkage (``kinematics.md`` §6), mm; axes need not be unit vectors.

    Attributes
    ----------
    O_A : input pivot on the input axis ``e``.
    e : input axis direction.
    a0 : input crank O_A -> S_A at theta = 0.
    d : O_A -> O_C, the output pivot on the output axis ``f``.
    f : output axis direction.
    b, c : coupler S_A-S_C and output crank O_C-S_C lengths.
    c1 : cosine of the output crank's angle to ``f`` (0: the crank is perpendicular to its axis).
    branch : +1 or -1, the assembly: the sign of ``(S_C - O_C) . (f x (O_C - S_A))``.
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


#: The spec's synthetic completion of the thesis RSSR (``kinematics.md`` §6.5).
THESIS_RSSR = RSSRGeometry()
#: Input crank speed of the thesis experiment, rad/s.
THESIS_THETA_DOT = 0.58


@dataclass(frozen=True)
class RSSRMotion:
    """Joint positions ``S_A``, ``S_C`` (..., 3) mm and the output angle ``phi`` (rad, from its
    theta = 0 position, right-handed about ``f``, in [-pi, pi]) with its rate and acceleration."""

    S_A: FloatArray
    S_C: FloatArray
    phi: FloatArray
    phi_dot: FloatArray
    phi_ddot: FloatArray


def _output_crank(theta: FloatArray, g: RSSRGeometry) -> tuple[FloatArray, FloatArray]:
    """Input crank ``a`` and output crank ``c`` vectors (..., 3), mm, at input angles ``theta``.

    The output crank tip lies on the circle ``O_C + c (c1 f + s (cos psi u + sin psi w))``; at the
    coupler's length ``b`` from ``S_A`` that is ``A cos psi + B sin psi = K``, two solutions
    ``psi = atan2(B, A) +- acos(K / hypot(A, B))``, the ``+`` one on the ``branch = +1`` side.
    """
    e, f = _unit(g.e), _unit(g.f)
    a = rotate(np.asarray(g.a0, float), e, theta)
    v = np.asarray(g.d, float) - a                                   # S_A -> O_C
    u = _unit(np.cross(f, [1.0, 0.0, 0.0]) if abs(f[0]) < 0.9 else np.cross(f, [0.0, 1.0, 0.0]))
    w = np.cross(f, u)
    s = np.sqrt(1.0 - g.c1 ** 2)
    K = (g.b ** 2 - g.c ** 2 - _dot(v, v)) / (2.0 * g.c) - g.c1 * (v @ f)
    A, B = s * (v @ u), s * (v @ w)
    rho = np.hypot(A, B)
    if np.any(np.abs(K) > rho):
        k = int(np.flatnonzero(np.ravel(np.abs(K) > rho))[0])
        raise ValueError(f"the RSSR linkage cannot close at theta = {np.ravel(theta)[k]:.6g} rad: the output "
                         "crank's circle does not reach the coupler; check the lengths b, c and the pivots")
    psi = np.arctan2(B, A) + g.branch * np.arccos(K / rho)
    c_hat = g.c1 * f + s * (np.cos(psi)[..., None] * u + np.sin(psi)[..., None] * w)
    return a, g.c * c_hat


def rssr_motion(theta: ArrayLike, theta_dot: ArrayLike = THESIS_THETA_DOT, theta_ddot: ArrayLike = 0.0,
                geometry: RSSRGeometry = THESIS_RSSR) -> RSSRMotion:
    """Positions and output angle, rate and acceleration of an RSSR linkage at input angles ``theta``.

    The rates come from the coupler's fixed length: with ``r = S_C - S_A``, ``r . (dS_C - dS_A) = 0``
    gives ``phi_dot = theta_dot r.(e x a) / r.(f x c)``, and its derivative
    ``|dS_C - dS_A|² + r . (ddS_C - ddS_A) = 0`` gives ``phi_ddot``.

    Parameters
    ----------
    theta : input angles (rad) about ``e`` from ``a0``.
    theta_dot, theta_ddot : input rate (rad/s) and acceleration (rad/s²).
    geometry : the linkage (default the thesis's, :data:`THESIS_RSSR`).

    Raises
    ------
    ValueError
        The linkage cannot close, or it is at a toggle position (the output rate is undefined).

    Examples
    --------
    >>> m = rssr_motion(0.0)
    >>> m.S_C.round(3).tolist(), round(float(m.phi_dot), 6), round(float(m.phi_ddot), 6)
    ([-169.63, -120.373, -79.398], 0.227955, -0.219261)
    """
    g = geometry
    if g.branch not in (1, -1):
        raise ValueError(f"RSSR branch must be +1 or -1, got {g.branch}")
    th = np.asarray(theta, dtype=float)
    td, tdd = np.asarray(theta_dot, dtype=float)[..., None], np.asarray(theta_ddot, dtype=float)[..., None]
    e, f = _unit(g.e), _unit(g.f)
    a, c = _output_crank(th, g)
    _, c0 = _output_crank(np.asarray(0.0), g)
    O_A = np.asarray(g.O_A, float)
    S_A, S_C = O_A + a, O_A + np.asarray(g.d, float) + c
    r = S_C - S_A
    f_c = np.cross(f, c)
    den = _dot(r, f_c)
    if np.any(np.abs(den) <= 1e-9 * g.b * g.c):
        k = int(np.flatnonzero(np.ravel(np.abs(den) <= 1e-9 * g.b * g.c))[0])
        raise ValueError(f"the RSSR linkage is at a toggle position at theta = {np.ravel(th)[k]:.6g} rad: "
                         "the coupler is in the plane of the output crank's motion")
    e_a = np.cross(e, a)
    phi_dot = td[..., 0] * _dot(r, e_a) / den
    v_A, v_C = td * e_a, phi_dot[..., None] * f_c
    acc_A = tdd * e_a + td ** 2 * np.cross(e, e_a)
    rel = v_C - v_A
    phi_ddot = (-_dot(rel, rel) + _dot(r, acc_A) - phi_dot ** 2 * _dot(r, np.cross(f, f_c))) / den
    # output angle: the crank's turn about f since theta = 0, from the components normal to f
    p0, p = c0 - (c0 @ f) * f, c - (c @ f)[..., None] * f
    phi = np.arctan2(_dot(np.cross(p0, p), np.broadcast_to(f, p.shape)), _dot(np.broadcast_to(p0, p.shape), p))
    return RSSRMotion(S_A, S_C, phi, phi_dot, phi_ddot)


# --------------------------------------------------------------------------------------------- box
def box_inertia(mass: float, size_m: ArrayLike) -> FloatArray:
    """Principal moments (kg·m²) of a uniform box of edges ``size_m`` (m) about its centre.

    Examples
    --------
    >>> box_inertia(2.2, [0.2, 0.2, 0.3]).round(7).tolist()
    [0.0238333, 0.0238333, 0.0146667]
    """
    sq = np.asarray(size_m, dtype=float) ** 2
    return mass * (sq.sum() - sq) / 12.0


def box_vertices(size_mm: ArrayLike) -> FloatArray:
    """The 8 vertices (8, 3) mm of a box centred at the origin, edges along the axes: signs
    ``(±x, ±y, ±z)`` with x varying slowest (vertex ``4 i + 2 j + k`` has signs of bits i, j, k)."""
    signs = np.array([[(n >> 2) & 1, (n >> 1) & 1, n & 1] for n in range(8)], dtype=float) * 2.0 - 1.0
    return signs * (0.5 * np.asarray(size_mm, dtype=float))


def _quaternion_matrix(q: FloatArray) -> FloatArray:
    """Rotation matrices (T, 3, 3) of unit quaternions (T, 4) ``(w, x, y, z)``."""
    w, x, y, z = (q / np.linalg.norm(q, axis=1, keepdims=True)).T
    return np.stack([np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
                     np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
                     np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1)], -2)


def torque_free_rotation(inertia: ArrayLike, omega0_body: ArrayLike, t: ArrayLike,
                         tol: float = 1e-12) -> tuple[FloatArray, FloatArray]:
    """Attitude ``R`` (T, 3, 3) body -> world (identity at ``t[0]``) and body rate (T, 3) rad/s of a
    torque-free rigid body, at times ``t`` (s, increasing, from the initial time).

    Euler's equations ``I dw/dt = (I w) x w`` with the attitude as a unit quaternion,
    ``dq/dt = q (0, w) / 2``, integrated together by DOP853 at ``tol`` (relative and absolute).

    Examples
    --------
    >>> R, w = torque_free_rotation(box_inertia(2.2, [0.2, 0.2, 0.3]), [3.0, 1.0, 6.0], np.linspace(0, 1, 5))
    >>> H = np.einsum("tij,tj->ti", R, box_inertia(2.2, [0.2, 0.2, 0.3]) * w)
    >>> bool(np.allclose(H, [0.0715, 0.0238333, 0.088], atol=1e-6))
    True
    """
    I = np.asarray(inertia, dtype=float)
    tt = np.asarray(t, dtype=float)

    def rhs(_: float, y: FloatArray) -> FloatArray:
        w, q = y[:3], y[3:]
        dq = 0.5 * np.array([-q[1:] @ w, *(q[0] * w + np.cross(q[1:], w))])
        return np.concatenate([np.cross(I * w, w) / I, dq])

    y0 = np.concatenate([np.asarray(omega0_body, dtype=float), [1.0, 0.0, 0.0, 0.0]])
    sol = solve_ivp(rhs, (tt[0], tt[-1]), y0, t_eval=tt, method="DOP853", rtol=tol, atol=tol)
    return _quaternion_matrix(sol.y[3:].T), sol.y[:3].T
