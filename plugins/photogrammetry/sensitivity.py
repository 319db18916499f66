"""Error analysis: numerical sensitivities, Monte Carlo propagation, error maps and the rotating table.

Thesis §2.4 (eqs 2.29–2.31), §2.5 (eq. 2.32 corrected, Tables 2.1–2.3) and §3.5 (Table 3.1,
Figs 3.22–3.23); spec §4, §5, §11. Lengths in mm, angles in rad, right-handed world frames.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .central import CentralCamera, reconstruct_chain_central
from .errors import InvalidArgument, RayMissesSphere

__all__ = [
    "SensitivityResult",
    "sensitivity",
    "monte_carlo",
    "MonteCarloResult",
    "THESIS_CENTRAL_ERRORS",
    "central_point_sensitivity",
    "sphere_points",
    "central_error_map",
    "table_rotation",
    "rotating_table_points",
    "fit_table_angles",
    "accuracy_statistics",
    "THESIS_MIRROR_ERRORS",
    "MirrorScene",
    "mirror_reconstruct",
    "mirror_point_sensitivity",
    "mirror_error_map",
    "mirror_angle_sweep",
]


# ------------------------------------------------------------------------------------------------
# Generic sensitivities (2.29)–(2.31)
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class SensitivityResult:
    """Per-parameter contributions ``c_n = dR/da_n * da_n`` (eq. 2.30).

    Attributes
    ----------
    names : tuple of str
    value : ndarray (...)
        Unperturbed reconstruction R.
    derivatives : ndarray (P, ...)
        Central-difference derivatives dR/da_n (eq. 2.31).
    contributions : ndarray (P, ...)
        ``derivatives * errors`` (mm).
    steps : ndarray (P,)
        Steps actually used (after halving).
    halvings : ndarray of int (P,)
        How often each step was halved because a perturbed evaluation raised RayMissesSphere.
    """

    names: tuple
    value: NDArray[np.float64]
    derivatives: NDArray[np.float64]
    contributions: NDArray[np.float64]
    steps: NDArray[np.float64]
    halvings: NDArray[np.int_]

    @property
    def signed_sum(self) -> NDArray[np.float64]:
        """``sum_n c_n`` — the thesis quantity (2.30)."""
        return self.contributions.sum(axis=0)

    @property
    def abs_sum(self) -> NDArray[np.float64]:
        """``sum_n |c_n|`` — worst case."""
        return np.abs(self.contributions).sum(axis=0)

    @property
    def rss(self) -> NDArray[np.float64]:
        """``sqrt(sum_n c_n^2)`` — independent random errors."""
        return np.sqrt((self.contributions**2).sum(axis=0))

    def as_dict(self) -> dict[str, NDArray[np.float64]]:
        """``{name: contribution}``."""
        return dict(zip(self.names, self.contributions))


def _as_vector(params: Mapping[str, float] | ArrayLike) -> tuple[tuple, NDArray, Callable[[NDArray], Any]]:
    if isinstance(params, Mapping):
        names = tuple(params)
        vec = np.array([float(params[k]) for k in names])
        return names, vec, lambda v: dict(zip(names, v))
    vec = np.asarray(params, dtype=float).ravel()
    return tuple(str(i) for i in range(vec.size)), vec, lambda v: v


def sensitivity(
    reconstruct: Callable[[Any], ArrayLike],
    params: Mapping[str, float] | ArrayLike,
    errors: Mapping[str, float] | ArrayLike,
    step: Mapping[str, float] | ArrayLike | None = None,
    max_halvings: int = 10,
) -> SensitivityResult:
    """Numerical sensitivity of a reconstruction to each parameter (eqs 2.29–2.31).

    Parameters
    ----------
    reconstruct : callable
        ``reconstruct(params) -> array`` (any shape, e.g. (3,) or (M, 3) for M points at once);
        receives a dict if ``params`` is a mapping, else a 1-D array.
    params : mapping or array_like
        Nominal parameter values a_n (mm, rad, ...).
    errors : mapping or array_like
        Measurement errors da_n in the same units and order.
    step : mapping or array_like, optional
        Difference steps Delta a_n; default ``Delta a_n = da_n`` (spec §4).
    max_halvings : int
        A perturbed evaluation that raises RayMissesSphere is retried with half the step, up to this
        many times (reported in ``halvings``).

    Returns
    -------
    SensitivityResult

    Examples
    --------
    >>> r = sensitivity(lambda p: np.array([p["a"] * p["b"], p["b"]]), {"a": 2.0, "b": 3.0},
    ...                 {"a": 0.1, "b": 0.01})
    >>> np.round(r.contributions, 6).tolist()
    [[0.3, 0.0], [0.02, 0.01]]
    """
    names, p0, wrap = _as_vector(params)
    err = np.array([float(errors[k]) for k in names]) if isinstance(errors, Mapping) else np.asarray(errors, float).ravel()
    if err.shape != p0.shape:
        raise InvalidArgument(f"errors must give one value per parameter ({len(names)}), got {err.size}")
    if step is None:
        h = err.copy()
    else:
        h = np.array([float(step[k]) for k in names]) if isinstance(step, Mapping) else np.asarray(step, float).ravel()
    if np.any(h <= 0):
        raise InvalidArgument("steps (default: the errors) must be > 0")
    value = np.asarray(reconstruct(wrap(p0)), dtype=float)
    derivs = np.empty((len(p0),) + value.shape)
    halvings = np.zeros(len(p0), dtype=int)
    for n in range(len(p0)):  # one pair of evaluations per parameter; each is vectorised over points
        for k in range(max_halvings + 1):
            e = np.zeros_like(p0)
            e[n] = h[n]
            try:
                plus = np.asarray(reconstruct(wrap(p0 + e)), dtype=float)
                minus = np.asarray(reconstruct(wrap(p0 - e)), dtype=float)
                break
            except RayMissesSphere:
                if k == max_halvings:
                    raise
                h[n] /= 2
                halvings[n] += 1
        derivs[n] = (plus - minus) / (2 * h[n])  # (2.31) corrected: 2 Delta a_n
    contrib = derivs * err.reshape((-1,) + (1,) * value.ndim)
    return SensitivityResult(names, value, derivs, contrib, h, halvings)


@dataclass(frozen=True)
class MonteCarloResult:
    """Samples of a Monte Carlo error propagation."""

    samples: NDArray[np.float64]
    value: NDArray[np.float64]

    @property
    def bias(self) -> NDArray[np.float64]:
        return self.samples.mean(axis=0) - self.value

    @property
    def std(self) -> NDArray[np.float64]:
        return self.samples.std(axis=0, ddof=1)


def monte_carlo(
    reconstruct: Callable[[Any], ArrayLike],
    params: Mapping[str, float] | ArrayLike,
    errors: Mapping[str, float] | ArrayLike,
    n: int = 500,
    rng: np.random.Generator | int | None = None,
    distribution: str = "normal",
    vectorized: bool = False,
) -> MonteCarloResult:
    """Propagate random parameter errors by sampling (normal with s.d. ``errors`` or uniform ±errors).

    ``vectorized=True`` calls ``reconstruct`` once with every parameter an array of ``n`` samples
    and expects output of shape (n, ...); otherwise it is called once per sample.
    Returns a :class:`MonteCarloResult` (``samples`` (n, ...), ``value``, ``bias``, ``std``).

    Examples
    --------
    >>> mc = monte_carlo(lambda p: 2 * p["a"][:, None], {"a": 1.0}, {"a": 0.1}, n=4000, rng=0, vectorized=True)
    >>> bool(abs(mc.std[0] - 0.2) < 0.01)
    True
    """
    names, p0, wrap = _as_vector(params)
    err = np.array([float(errors[k]) for k in names]) if isinstance(errors, Mapping) else np.asarray(errors, float).ravel()
    g = np.random.default_rng(rng)
    if distribution == "normal":
        d = g.normal(size=(n, len(p0))) * err
    elif distribution == "uniform":
        d = g.uniform(-1, 1, size=(n, len(p0))) * err
    else:
        raise InvalidArgument("distribution must be 'normal' or 'uniform'")
    samples = p0 + d
    if vectorized:
        value = np.asarray(reconstruct(wrap(p0[:, None])), dtype=float)[0]
        out = np.asarray(reconstruct(wrap(samples.T)), dtype=float)
    else:
        value = np.asarray(reconstruct(wrap(p0)), dtype=float)
        out = np.stack([np.asarray(reconstruct(wrap(s)), dtype=float) for s in samples])
    return MonteCarloResult(out, value)


# ------------------------------------------------------------------------------------------------
# Central projection (§2.4): one link from a start point (default K)
# ------------------------------------------------------------------------------------------------

#: Thesis parameter errors of §2.4 (mm, rad).
THESIS_CENTRAL_ERRORS: dict[str, float] = {
    "x": 0.01, "y": 0.01, "f": 0.01, "alpha": float(np.radians(0.2)), "link": 1.0, "a": 1.0,
}


def central_point_sensitivity(
    points: ArrayLike,
    camera: CentralCamera,
    errors: Mapping[str, float] = THESIS_CENTRAL_ERRORS,
    step: Mapping[str, float] | None = None,
) -> SensitivityResult:
    """Sensitivity of markers reconstructed on one link from K (spec §4 reference geometry).

    Each point P (M, 3) is imaged by ``camera`` and reconstructed by :func:`reconstruct_chain_central`
    from the (perturbed) camera's K with link length |P - K|, picking the root closest to P.
    Parameters: film ``x``, ``y`` (mm; the same perturbation applied to every point), ``f``, ``alpha``,
    ``link`` (link length), ``a``.

    Returns
    -------
    SensitivityResult
        ``contributions`` shape (6, M, 3) (mm).

    Examples
    --------
    >>> cam = CentralCamera(2687.0, 54.0, np.radians(12))
    >>> r = central_point_sensitivity(cam.K + [[0, 0, -300.0]], cam)
    >>> np.round(r.as_dict()["x"][0], 3).tolist()
    [0.424, 0.0, 0.0]
    """
    P = np.atleast_2d(np.asarray(points, dtype=float))
    xy = camera.project(P)
    D = np.linalg.norm(P - camera.K, axis=-1)
    p0 = {"x": 0.0, "y": 0.0, "f": camera.f, "alpha": camera.alpha, "link": 0.0, "a": camera.a}

    def rec(p):
        cam = CentralCamera(p["a"], p["f"], p["alpha"])
        img = xy + np.array([p["x"], p["y"]])
        return reconstruct_chain_central(img[:, None, :], (D + p["link"])[:, None], cam, reference=P[:, None, :]).points[:, 0]

    return sensitivity(rec, p0, {k: errors[k] for k in p0}, step)


def sphere_points(center: ArrayLike, radius: float, n_lat: int = 13, n_lon: int = 24) -> NDArray[np.float64]:
    """Points on a sphere (latitude rings incl. poles) about ``center``, shape (M, 3) (mm).

    Examples
    --------
    >>> sphere_points([0, 0, 0], 1.0, 3, 4).shape
    (6, 3)
    """
    lat = np.linspace(-np.pi / 2, np.pi / 2, n_lat)[1:-1]
    lon = np.linspace(0, 2 * np.pi, n_lon, endpoint=False)
    la, lo = np.meshgrid(lat, lon, indexing="ij")
    ring = np.stack([np.cos(la) * np.sin(lo), np.sin(la), np.cos(la) * np.cos(lo)], axis=-1).reshape(-1, 3)
    pts = np.concatenate([[[0, -1, 0]], ring, [[0, 1, 0]]])
    return np.asarray(center, float) + radius * pts


def central_error_map(
    camera: CentralCamera, radius: float = 300.0, n_lat: int = 13, n_lon: int = 24,
    errors: Mapping[str, float] = THESIS_CENTRAL_ERRORS,
) -> tuple[NDArray[np.float64], SensitivityResult]:
    """Error map of Fig. 2.11: markers on a sphere of ``radius`` about K (one link from K).

    Returns the points (M, 3) and their :class:`SensitivityResult`. Points within 1e-6 of tangency
    may trigger step halving (reported in the result).
    """
    pts = sphere_points(camera.K, radius, n_lat, n_lon)
    return pts, central_point_sensitivity(pts, camera, errors)


# ------------------------------------------------------------------------------------------------
# Rotating table (§2.5, eq. 2.32 corrected)
# ------------------------------------------------------------------------------------------------


def _rx(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def _ry(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(t):
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def table_rotation(theta: float, phi: float, psi: float) -> NDArray[np.float64]:
    """``R_Y(phi) R_X(theta) R_Z(psi)`` of the corrected eq. 2.32 (rad; rotations about X, Y, Z).

    Examples
    --------
    >>> np.allclose(table_rotation(0.1, 0.2, 0.3) @ table_rotation(0.1, 0.2, 0.3).T, np.eye(3))
    True
    """
    return _ry(phi) @ _rx(theta) @ _rz(psi)


def rotating_table_points(
    theta: float, phi: float, psi: float, z_k: float = 2479.37, half_side: float = 252.0
) -> NDArray[np.float64]:
    """World coordinates (4, 3) of the table corners 1..4 for table angles (rad), eq. 2.32.

    Examples
    --------
    >>> rotating_table_points(0, 0, 0)[0].tolist()
    [252.0, 0.0, 2227.37]
    """
    h = half_side
    corners = np.array([[h, 0, -h], [-h, 0, -h], [-h, 0, h], [h, 0, h]], float)
    return corners @ table_rotation(theta, phi, psi).T + np.array([0, 0, z_k])


def fit_table_angles(points: ArrayLike, z_k: float = 2479.37, half_side: float = 252.0,
                     x0: ArrayLike = (0.0, 0.0, 0.0)) -> tuple[NDArray[np.float64], float]:
    """Least-squares table angles (theta, phi, psi) (rad) for 4 corner positions; returns (angles, RMS mm)."""
    P = np.asarray(points, float)
    sol = least_squares(lambda a: (rotating_table_points(*a, z_k, half_side) - P).ravel(), np.asarray(x0, float))
    return sol.x, float(np.sqrt(np.mean(sol.fun**2)))


def accuracy_statistics(given: ArrayLike, measured: ArrayLike) -> dict[str, NDArray[np.float64]]:
    """Error ``given - measured`` (..., 3), its signed mean per axis (systematic error) and max |error|.

    Examples
    --------
    >>> s = accuracy_statistics([[1.0, 2, 3], [0, 0, 0]], [[0.0, 0, 0], [1, 0, 0]])
    >>> s["mean"].tolist(), s["max_abs"].tolist()
    ([0.0, 1.0, 1.5], [1.0, 2.0, 3.0])
    """
    err = np.asarray(given, float) - np.asarray(measured, float)
    flat = err.reshape(-1, 3)
    return {"error": err, "mean": flat.mean(axis=0), "max_abs": np.abs(flat).max(axis=0),
            "rms": np.sqrt((flat**2).mean(axis=0))}


# ------------------------------------------------------------------------------------------------
# Mirror method (§3.5, Table 3.1, Figs 3.22–3.23)
# ------------------------------------------------------------------------------------------------

#: Perturbations of Table 3.1 (a): film coordinates (mm), F and G (mm), mirror normal angle T (rad).
THESIS_MIRROR_ERRORS: dict[str, float] = {
    "Ux": 0.003, "Uy": 0.003, "Vx": 0.003, "Vy": 0.003,
    "Fx": 1.0, "Fy": 1.0, "Fz": 1.0, "Gx": 1.0, "Gz": 1.0, "T": 1e-4,
}

#: Fixed parameters of the thesis program (Appendix 2, DATA 2800) and its calibration grid (DATA 2900).
THESIS_F1 = np.array([435.68, 202.6, 1442.024])
THESIS_G = np.array([-291.62, -52.76, 487.56])
THESIS_GRID_X = np.array([-849, -728.5, -607.5, -485, -364, -241.5, -120.5, 0, 121, 243, 365, 486, 607], float)
THESIS_GRID_Y = np.array([-486, -365, -244, -122, 0, 121, 243], float)


def _mirror_normal_from_angle(T: float) -> NDArray[np.float64]:
    """Vertical mirror rotated about Y: n = (cos T, 0, sin T)."""
    return np.array([np.cos(T), 0.0, np.sin(T)])


@dataclass(frozen=True)
class MirrorScene:
    """Shooting condition of a mirror-method error analysis (vertical mirror, spec §10/§11).

    Attributes
    ----------
    calibration : PlaneCalibration
        Fixed image -> calibration-plane map (eqs 3.15–3.20); it does not change when F or G is
        perturbed, which is how errors of F enter the rays (eq. 3.20).
    camera_center : ndarray (3,)
        F1 (mm).
    mirror_point : ndarray (3,)
        G (mm).
    mirror_angle : float
        T (rad): the mirror normal is ``(cos T, 0, sin T)`` (vertical mirror turned about Y).
    """

    calibration: Any
    camera_center: NDArray[np.float64]
    mirror_point: NDArray[np.float64]
    mirror_angle: float

    @property
    def normal(self) -> NDArray[np.float64]:
        return _mirror_normal_from_angle(self.mirror_angle)

    @classmethod
    def thesis(cls, mirror_angle: float = float(np.radians(50.0)), focal: float = 30.0) -> MirrorScene:
        """§10 geometry: camera at F1 looking along -Z (film parallel to Z = 0), ``focal`` mm lens,
        G of DATA 2800, calibrated (quadratic, exact here) on the 91-point grid of DATA 2900."""
        from .cameras import fit_plane_calibration

        grid = np.stack(np.meshgrid(THESIS_GRID_X, THESIS_GRID_Y, indexing="ij"), axis=-1).reshape(-1, 2)
        d = np.c_[grid, np.zeros(len(grid))] - THESIS_F1
        film = focal * np.c_[d[:, 0], -d[:, 1]] / -d[:, 2:3]  # camera axes x = X, y = -Y, z = -Z
        cal = fit_plane_calibration(film, grid, 0.0, THESIS_F1)
        return cls(cal, THESIS_F1.copy(), THESIS_G.copy(), float(mirror_angle))

    def with_angle(self, mirror_angle: float) -> MirrorScene:
        return MirrorScene(self.calibration, self.camera_center, self.mirror_point, float(mirror_angle))

    def image_points(self, points: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Film coordinates (M, 2) of the markers (U) and of their mirror images (V)."""
        from .mirror import reflect

        P = np.atleast_2d(np.asarray(points, float))
        U = self.calibration.project(P)
        V = self.calibration.project(reflect(P, self.mirror_point, self.normal))
        return U, V


def mirror_reconstruct(scene: MirrorScene, U: ArrayLike, V: ArrayLike, params: Mapping[str, float] | None = None
                       ) -> NDArray[np.float64]:
    """Markers (M, 3) from film coordinates U (direct) and V (mirror image) with offsets ``params``.

    ``params`` keys (all offsets, default 0): Ux, Uy, Vx, Vy (mm on the film), Fx, Fy, Fz, Gx, Gz (mm),
    T (rad, added to the mirror angle). Pipeline of spec §9: plane map (3.15–3.16) -> rays (3.20)
    -> virtual camera (3.11–3.13) -> midpoint triangulation (3.5–3.7).
    """
    from .mirror import triangulate_mirror

    p = {k: 0.0 for k in THESIS_MIRROR_ERRORS}
    p.update(params or {})
    U = np.asarray(U, float) + [p["Ux"], p["Uy"]]
    V = np.asarray(V, float) + [p["Vx"], p["Vy"]]
    F = scene.camera_center + [p["Fx"], p["Fy"], p["Fz"]]
    G = scene.mirror_point + [p["Gx"], 0.0, p["Gz"]]
    n = _mirror_normal_from_angle(scene.mirror_angle + p["T"])
    zc = scene.calibration.plane_z

    def ray(xy):
        XY = scene.calibration.map_to_plane(xy)
        return np.c_[XY, np.full(len(XY), zc)] - F

    return triangulate_mirror(F, G, n, ray(U), ray(V)).points


def mirror_point_sensitivity(
    scene: MirrorScene, points: ArrayLike, errors: Mapping[str, float] = THESIS_MIRROR_ERRORS
) -> SensitivityResult:
    """Table 3.1: contribution of each parameter error to the reconstructed markers (10, M, 3) mm.

    Examples
    --------
    >>> r = mirror_point_sensitivity(MirrorScene.thesis(), [[100.0, 50.0, 300.0]])
    >>> r.contributions.shape
    (10, 1, 3)
    """
    U, V = scene.image_points(points)
    p0 = {k: 0.0 for k in errors}
    return sensitivity(lambda p: mirror_reconstruct(scene, U, V, p), p0, errors)


def mirror_error_map(
    scene: MirrorScene, center: ArrayLike = (100.0, 50.0, 300.0), radius: float = 100.0,
    n_lat: int = 9, n_lon: int = 16, errors: Mapping[str, float] = THESIS_MIRROR_ERRORS,
) -> tuple[NDArray[np.float64], SensitivityResult]:
    """Fig. 3.22: markers on a sphere (default 200 mm diameter) about ``center``; returns points and sensitivities."""
    pts = sphere_points(center, radius, n_lat, n_lon)
    return pts, mirror_point_sensitivity(scene, pts, errors)


def mirror_angle_sweep(
    scene: MirrorScene, points: ArrayLike, angles: ArrayLike,
    errors: Mapping[str, float] = THESIS_MIRROR_ERRORS, measure: str = "abs_sum",
) -> NDArray[np.float64]:
    """Fig. 3.23: total error vs mirror angle T (rad), mirror turned about the vertical through G.

    For each angle the markers are re-imaged (direct and mirror image) and the sensitivity is
    evaluated; the measure per angle is the mean over ``points`` of the sum over parameters of the
    contribution magnitudes |c_n| (``"abs_sum"``) or of their root-sum-square (``"rss"``) (mm).
    """
    out = []
    for T in np.asarray(angles, float):  # one vectorised sensitivity per mirror angle
        r = mirror_point_sensitivity(scene.with_angle(T), points, errors)
        mag = np.linalg.norm(r.contributions, axis=-1)  # (P, M)
        tot = mag.sum(axis=0) if measure == "abs_sum" else np.sqrt((mag**2).sum(axis=0))
        out.append(tot.mean())
    return np.asarray(out)
