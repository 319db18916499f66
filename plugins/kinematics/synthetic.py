"""Synthetic validation fixtures: torque-free tumbling box (Euler's equations) and its markers.

Units: mm for marker positions, s, rad/s, kg·m² for inertia, kg·m²/s for angular momentum.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.integrate import solve_ivp

from .rigid import skew

__all__ = ["TumblingBody", "box_inertia", "box_vertices", "torque_free_rotation", "tumbling_box_markers"]

FloatArray = NDArray[np.float64]


def box_inertia(mass: float, size_m: ArrayLike) -> FloatArray:
    """Principal inertia (kg·m²) of a uniform box of edges ``size_m`` (m) about its centre.

    Examples
    --------
    >>> box_inertia(2.2, [0.2, 0.2, 0.3]).round(7).tolist()
    [0.0238333, 0.0238333, 0.0146667]
    """
    a, b, c = np.asarray(size_m, dtype=float)
    return mass / 12.0 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])


def box_vertices(size_mm: ArrayLike) -> FloatArray:
    """The 8 vertices (8, 3) in mm of a box centred at the origin, edges along the axes."""
    h = 0.5 * np.asarray(size_mm, dtype=float)
    s = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)
    return s * h


@dataclass(frozen=True)
class TumblingBody:
    """Torque-free rotation sampled at ``t``: ``R`` body->world, angular velocity in both frames."""

    t: FloatArray
    R: FloatArray
    omega_world: FloatArray
    omega_body: FloatArray
    H_world: FloatArray


def torque_free_rotation(
    inertia: ArrayLike, omega0_body: ArrayLike, t: ArrayLike, R0: ArrayLike | None = None,
    rtol: float = 1e-12, atol: float = 1e-12,
) -> TumblingBody:
    """Integrate Euler's equations and ``dR/dt = R [w_body]x`` (DOP853, tight tolerances).

    Parameters
    ----------
    inertia : array_like, shape (3,)
        Principal moments (kg·m²) along the body axes.
    omega0_body : array_like, shape (3,)
        Initial body-frame angular velocity (rad/s).
    t : array_like, shape (T,)
        Output times (s), starting at the initial time.
    R0 : array_like, shape (3, 3), optional
        Initial attitude (default identity).

    Examples
    --------
    >>> tb = torque_free_rotation(box_inertia(2.2, [0.2, 0.2, 0.3]), [3, 1, 6], np.linspace(0, 1, 43))
    >>> bool(np.allclose(tb.H_world, [0.0715, 0.0238333, 0.088], atol=1e-6))
    True
    """
    I = np.asarray(inertia, dtype=float)
    tt = np.asarray(t, dtype=float)
    R0m = np.eye(3) if R0 is None else np.asarray(R0, dtype=float)

    def rhs(_: float, y: FloatArray) -> FloatArray:
        w = y[:3]
        R = y[3:].reshape(3, 3)
        dw = (np.cross(I * w, w)) / I  # I w' = (I w) x w
        return np.concatenate([dw, (R @ skew(w)).ravel()])

    sol = solve_ivp(rhs, (tt[0], tt[-1]), np.concatenate([np.asarray(omega0_body, float), R0m.ravel()]),
                    t_eval=tt, method="DOP853", rtol=rtol, atol=atol)
    wb = sol.y[:3].T
    R = sol.y[3:].T.reshape(-1, 3, 3)
    U, _, Vt = np.linalg.svd(R)
    R = U @ Vt  # re-orthonormalise
    ww = np.einsum("tij,tj->ti", R, wb)
    H = np.einsum("tij,tj->ti", R, I * wb)
    return TumblingBody(tt, R, ww, wb, H)


def tumbling_box_markers(
    rate: float = 200.0, duration: float = 1.0, omega0_body: ArrayLike = (3.0, 1.0, 6.0),
    size_mm: ArrayLike = (200.0, 200.0, 300.0), mass: float = 2.2, noise_mm: float = 0.0,
    seed: int = 0,
) -> tuple[FloatArray, FloatArray, TumblingBody]:
    """Vertices (T, 8, 3) mm of a box tumbling torque-free while its centre flies ballistically.

    Returns ``(t, markers, body)``; Gaussian digitising noise of ``noise_mm`` per coordinate.
    """
    t = np.arange(int(round(duration * rate)) + 1) / rate
    body = torque_free_rotation(box_inertia(mass, np.asarray(size_mm) / 1000.0), omega0_body, t)
    centre = np.stack([1000.0 * t, 1500.0 + 4000.0 * t - 0.5 * 9806.65 * t**2, 200.0 * t], -1)
    m = np.einsum("tij,mj->tmi", body.R, box_vertices(size_mm)) + centre[:, None]
    if noise_mm:
        m = m + np.random.default_rng(seed).normal(0.0, noise_mm, m.shape)
    return t, m, body


def analytic_signals() -> dict[str, tuple]:
    """Analytic test signals ``name -> (f, f', f'')`` (t in s; unit-free values).

    sine: ``sin(2 pi 1.5 t)``; polynomial: ``t^3 - 2 t^2 + 0.5 t``; exponential: ``exp(2 t)``.
    """
    w = 2 * np.pi * 1.5
    return {
        "sine": (lambda t: np.sin(w * t), lambda t: w * np.cos(w * t), lambda t: -w * w * np.sin(w * t)),
        "polynomial": (lambda t: t**3 - 2 * t**2 + 0.5 * t, lambda t: 3 * t**2 - 4 * t + 0.5,
                       lambda t: 6 * t - 4),
        "exponential": (lambda t: np.exp(2 * t), lambda t: 2 * np.exp(2 * t), lambda t: 4 * np.exp(2 * t)),
    }


def derivative_errors(
    method: str, rate: float = 42.0, duration: float = 1.0, window: tuple[float, float] = (0.2, 0.8),
    noise: float = 0.0, seed: int = 0, **params: object,
) -> dict[str, tuple[float, float, float]]:
    """Max errors of value, velocity, acceleration on ``window`` relative to each signal's max |.|.

    Sampling as in the thesis accuracy example (42 frames/s over 1 s). Returns
    ``name -> (value_err, velocity_err, acceleration_err)``.
    """
    from .derivatives import derivatives

    t = np.arange(int(round(duration * rate)) + 1) / rate
    rng = np.random.default_rng(seed)
    out = {}
    for name, (f, f1, f2) in analytic_signals().items():
        x = f(t) + (rng.normal(0.0, noise, t.size) if noise else 0.0)
        xs, v, a = derivatives(t, x, method=method, **params)
        sl = (t >= window[0] - 1e-12) & (t <= window[1] + 1e-12)
        dense = np.linspace(0, duration, 2001)
        errs = []
        for est, ref in ((xs, f), (v, f1), (a, f2)):
            errs.append(float(np.nanmax(np.abs(est[sl] - ref(t[sl]))) / np.max(np.abs(ref(dense)))))
        out[name] = tuple(errs)
    return out
