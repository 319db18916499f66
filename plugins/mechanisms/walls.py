"""The constrained swept-area problem of §6.2.1 (``analysis.md`` §5.3-§6).

A rod AB of length ``l`` moves from vertical (``A = (0, l)``, ``B = (0, 0)``) to horizontal
(``A`` at the origin, ``B = (-l, 0)``) with B on the x axis and A guided by a wall ``x = w(y)``:
``B = (w(y_A) - sqrt(l^2 - y_A^2), 0)``. Positions are sampled at equal steps of the rod's angle
from the vertical (``y_A = l cos(phi)``). Units: those of ``l`` (the thesis uses l = 3).

* :func:`wall_motion` — rod positions for a wall given as a function or as the 59-node polyline of
  Fig. 6.12; :func:`astroid_motion` (vertical wall, area 3 pi l^2 / 32), :func:`eq63_motion`
  (the wall of eq. 6.3 whose fixed centrode is the line y = h), :func:`arc_wall` (Fig. 6.11).
* :func:`centrodes` — instantaneous centres of any planar segment motion: the fixed centrode
  (world) and the moving centrode (rod frame).
* :func:`wall_area` — the area of a polyline wall and its gradient (strip formula; the area is
  linear in the wall abscissae for each extreme crossing, so the gradient is exact per piece).
* :func:`arc_grid` — the circular-arc grid search; :func:`optimal_wall` — the 59-variable problem
  by Fletcher-Reeves conjugate gradients (the thesis's method) or L-BFGS-B.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import brentq, minimize, minimize_scalar

from .errors import DegenerateGeometry, InvalidPoints
from .swept import strip_area

__all__ = ["ARC_C", "ARC_H", "ArcGrid", "OptimalWall", "THESIS_WALL_NODES", "WALL_LOWER_BOUND", "arc_grid", "arc_wall",
           "astroid_motion", "centrodes", "eq63_motion", "eq63_theta_q", "optimal_wall", "wall_area", "wall_motion",
           "wall_objective"]

FloatArray = NDArray[np.float64]
#: The thesis's wall nodes: y_i = 0.05 i, i = 0..60 (w_0 = w_60 = 0 fixed; 59 variables), l = 3.
THESIS_WALL_NODES = 0.05 * np.arange(61)
#: The walls :func:`optimal_wall` searches stay right of the y axis (``w >= 0``). This loses no
#: optimum: the starting (vertical) rod already covers x = 0 at every height, so moving a part of
#: the wall that lies left of the axis onto it leaves every strip's right end where it is and moves
#: every rod that touched it to the right, never sweeping more. Without the bound the low nodes are
#: nearly free (their rods are seldom an extreme crossing) and a solver leaves them wherever a
#: step put them: a dip to w = -0.02 at y = 0.15 that sweeps 6e-5 more than the clipped wall.
WALL_LOWER_BOUND = 0.0


def astroid_motion(l: float = 3.0, positions: int = 1000) -> tuple[FloatArray, FloatArray]:
    """Rod ends ``(a, b)`` (positions, 2) guided by orthogonal walls (A on the y axis, eq. 6.1).

    Examples
    --------
    >>> a, b = astroid_motion(3.0, 3)
    >>> a.round(6).tolist(), b.round(6).tolist()
    ([[0.0, 3.0], [0.0, 2.12132], [0.0, 0.0]], [[0.0, 0.0], [-2.12132, 0.0], [-3.0, 0.0]])
    """
    return wall_motion(lambda y: np.zeros_like(y), l, positions)


def wall_motion(wall: Callable[[FloatArray], FloatArray] | ArrayLike, l: float = 3.0, positions: int = 1000,
                nodes: ArrayLike | None = None) -> tuple[FloatArray, FloatArray]:
    """Rod ends for A sliding down a wall ``x = w(y)`` from ``(w(l), l)`` to ``(w(0), 0)``.

    Parameters
    ----------
    wall : a function ``w(y)`` (vectorised), or the abscissae at ``nodes`` (a polyline).
    l : rod length.
    positions : number of positions, at equal steps of the rod angle from the vertical.
    nodes : heights of the polyline nodes (default :data:`THESIS_WALL_NODES` scaled to ``l``;
        with 59 values the end nodes ``w_0 = w_60 = 0`` are added).

    Returns
    -------
    a, b : (positions, 2) end positions.
    """
    y = l * np.cos(np.linspace(0.0, np.pi / 2, positions))
    y[-1] = 0.0
    x = _polyline(wall, l, nodes)(y) if not callable(wall) else np.asarray(wall(y), dtype=float)
    a = np.stack([x, y], -1)
    b = np.stack([x - np.sqrt(np.maximum(l * l - y * y, 0.0)), np.zeros_like(y)], -1)
    return a, b


def _nodes_and_values(w: ArrayLike, l: float, nodes: ArrayLike | None) -> tuple[FloatArray, FloatArray]:
    v = np.asarray(w, dtype=float).ravel()
    ys = np.asarray(nodes, float) if nodes is not None else THESIS_WALL_NODES * (l / 3.0)
    if v.size == ys.size - 2:
        v = np.concatenate([[0.0], v, [0.0]])
    if v.size != ys.size:
        raise InvalidPoints(f"the wall has {v.size} abscissae for {ys.size} nodes; give {ys.size - 2} (inner "
                            f"nodes, ends fixed at 0) or {ys.size}")
    return ys, v


def _polyline(w: ArrayLike, l: float, nodes: ArrayLike | None) -> Callable[[FloatArray], FloatArray]:
    ys, v = _nodes_and_values(w, l, nodes)
    return lambda y: np.interp(y, ys, v)


def eq63_theta_q(l: float = 3.0, h: float = 2.2) -> float:
    """Angle θ_Q > 0 where the eq. 6.3 wall returns to the y axis (``l sin θ = h θ``).

    Examples
    --------
    >>> round(eq63_theta_q(3.0, 2.2), 3)
    1.321
    """
    if not 0 < h < l:
        raise DegenerateGeometry(f"eq. 6.3 needs 0 < h < l, got h = {h}, l = {l}")
    return float(brentq(lambda t: l * np.sin(t) - h * t, 1e-6, np.pi))


def eq63_motion(l: float = 3.0, h: float = 2.2, positions: int = 4000) -> tuple[FloatArray, FloatArray]:
    """Rod ends for the wall of eq. 6.3, ``a = l sin θ - h θ``, ``b = l cos θ`` (``B_x = -h θ``), to Q,
    then the astroid motion along the y axis (Fig. 6.7); equal steps of the rod angle θ.

    Examples
    --------
    >>> a, b = eq63_motion(3.0, 2.2, 4000)
    >>> round(strip_area(a, b, 4000), 4)        # spec §5.4: 2.515
    2.5159
    """
    theta = np.linspace(0.0, np.pi / 2, positions)
    tq = eq63_theta_q(l, h)
    on_wall = theta <= tq
    ax = np.where(on_wall, l * np.sin(theta) - h * theta, 0.0)
    ay = l * np.cos(theta)
    ay[-1] = 0.0
    bx = np.where(on_wall, -h * theta, -l * np.sin(theta))
    return np.stack([ax, ay], -1), np.stack([bx, np.zeros_like(bx)], -1)


def arc_wall(c: float, h: float, l: float = 3.0) -> Callable[[FloatArray], FloatArray]:
    """The arc wall of Fig. 6.11: circle of centre ``(c, h)`` through ``(0, l)``, followed clockwise
    to its second crossing of the y axis at ``y = 2h - l``, then the y axis.

    Examples
    --------
    >>> w = arc_wall(-1.0, 2.2)
    >>> w(np.array([3.0, 2.2, 1.4, 1.0])).round(6).tolist()
    [0.0, 0.280625, 0.0, 0.0]
    """
    R2 = c * c + (l - h) ** 2

    def w(y: FloatArray) -> FloatArray:
        y = np.asarray(y, dtype=float)
        on = (y >= 2 * h - l) & (y <= l)
        return np.where(on, c + np.sqrt(np.maximum(R2 - (y - h) ** 2, 0.0)), 0.0)

    return w


def centrodes(a: ArrayLike, b: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Fixed and moving centrodes of a planar segment motion (Fig. 6.6, 6.8).

    The instantaneous centre is the intersection of the normals to the velocities of A and B
    (velocities by central differences along the positions).

    Parameters
    ----------
    a, b : (T, 2) end positions in motion order.

    Returns
    -------
    fixed : (T, 2) centres in the world frame (NaN where the motion is a translation).
    moving : (T, 2) the same centres in the rod frame (origin B, x axis along BA).

    Examples
    --------
    >>> a, b = astroid_motion(3.0, 2001)
    >>> f, m = centrodes(a, b)
    >>> k = slice(10, -10)
    >>> float(np.abs(np.hypot(*f[k].T) - 3).max()) < 1e-5, float(np.abs(np.hypot(*(m[k] - [1.5, 0]).T) - 1.5).max()) < 1e-5
    (True, True)
    """
    A, B = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    vA, vB = np.gradient(A, axis=0), np.gradient(B, axis=0)
    M = np.stack([vA, vB], 1)                                   # (T, 2, 2): rows are the velocities
    rhs = np.stack([(A * vA).sum(1), (B * vB).sum(1)], 1)
    det = np.linalg.det(M)
    scale = np.linalg.norm(vA, axis=1) * np.linalg.norm(vB, axis=1)
    ok = np.abs(det) > 1e-12 * np.maximum(scale, 1e-300)
    fixed = np.full_like(A, np.nan)
    fixed[ok] = np.linalg.solve(M[ok], rhs[ok][..., None])[..., 0]
    ex = (A - B) / np.linalg.norm(A - B, axis=1, keepdims=True)
    d = fixed - B
    moving = np.stack([(d * ex).sum(1), ex[:, 0] * d[:, 1] - ex[:, 1] * d[:, 0]], 1)
    return fixed, moving


# ------------------------------------------------------------------------------------------------
# area of a polyline wall and its gradient
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class _Grid:
    """Precomputed sampling of the motion for polyline walls: positions, strips and hat weights."""

    l: float
    nodes: FloatArray
    pos_i: NDArray[np.int64]    # (N,) left wall node of each position's y_A
    pos_w: FloatArray           # (N,) weight of the right node
    strip_i: NDArray[np.int64]  # (K,) left wall node of each strip's height (A's own crossing)
    strip_w: FloatArray
    dy: float
    coef: FloatArray            # (K, N + 1): -s (1 - y / y_A) where y_A >= y, NaN elsewhere; last column
                                # 0 for A's path crossing (path=True) or NaN (positions only)

    @classmethod
    def make(cls, l: float, positions: int, strips: int, nodes: FloatArray, path: bool) -> _Grid:
        yA = l * np.cos(np.linspace(0.0, np.pi / 2, positions))[:-1]      # the last (horizontal) rod adds no area
        s = np.sqrt(np.maximum(l * l - yA * yA, 0.0))
        dy = l / strips
        y = (np.arange(strips) + 0.5) * dy

        def hat(v: FloatArray) -> tuple[NDArray[np.int64], FloatArray]:
            i = np.clip(np.searchsorted(nodes, v, side="right") - 1, 0, len(nodes) - 2)
            return i, (v - nodes[i]) / (nodes[i + 1] - nodes[i])

        with np.errstate(divide="ignore", invalid="ignore"):
            coef = np.where(yA[None] >= y[:, None], -s[None] * (1 - y[:, None] / yA[None]), np.nan)
        coef = np.hstack([coef, np.full((strips, 1), 0.0 if path else np.nan)])
        return cls(l, nodes, *hat(yA), *hat(y), dy, coef)

    def area_and_gradient(self, values: FloatArray) -> tuple[float, FloatArray]:
        hat_i = np.concatenate([self.pos_i, self.strip_i])
        hat_w = np.concatenate([self.pos_w, self.strip_w])
        ax_pos = values[self.pos_i] * (1 - self.pos_w) + values[self.pos_i + 1] * self.pos_w       # A_x per position
        ax_strip = values[self.strip_i] * (1 - self.strip_w) + values[self.strip_i + 1] * self.strip_w
        X = self.coef + np.hstack([np.broadcast_to(ax_pos, (len(ax_strip), len(ax_pos))), ax_strip[:, None]])
        hi, lo = np.nanargmax(X, axis=1), np.nanargmin(X, axis=1)
        k = np.arange(len(X))
        area = float((X[k, hi] - X[k, lo]).sum() * self.dy)
        grad = np.zeros(len(self.nodes))
        for idx, sign in ((hi, 1.0), (lo, -1.0)):
            # the candidate's hat: a position's own node, or (last column) the strip's node
            i = np.where(idx < len(self.pos_i), hat_i[np.minimum(idx, len(self.pos_i) - 1)], self.strip_i)
            w = np.where(idx < len(self.pos_i), hat_w[np.minimum(idx, len(self.pos_i) - 1)], self.strip_w)
            np.add.at(grad, i, sign * self.dy * (1 - w))
            np.add.at(grad, i + 1, sign * self.dy * w)
        return area, grad


def wall_area(w: ArrayLike, l: float = 3.0, positions: int = 4000, strips: int = 3000,
              nodes: ArrayLike | None = None, path: bool = True) -> float:
    """Swept area of a polyline wall (strip formula on ``positions`` x ``strips``).

    Parameters
    ----------
    w : wall abscissae: the 59 inner nodes (ends 0) or all 61 (thesis nodes ``y_i = 0.05 i l / 3``).
    l : rod length.
    positions : rod positions (equal angle steps).
    strips : horizontal strips of the quadrature.
    nodes : heights of the wall nodes (default the thesis's).
    path : include A's own crossing of each strip (see :func:`~.swept.strip_area`); ``False`` is the
        positions-only quadrature, biased low for bulged walls at a few hundred positions (the
        thesis's 2.486).

    Returns
    -------
    float
        Area (square units of ``l``).

    Examples
    --------
    >>> round(wall_area(np.zeros(59)), 4), round(3 * np.pi * 9 / 32, 4)
    (2.6507, 2.6507)
    """
    a, b = wall_motion(w, l, positions, nodes)
    return strip_area(a, b, strips, path=path)


def wall_objective(l: float = 3.0, positions: int = 400, strips: int = 1000,
                   objective: Literal["exact", "positions"] = "exact") -> Callable[[FloatArray], tuple[float, FloatArray]]:
    """The optimal-wall objective: inner abscissae (59,) -> (area, gradient (59,)).

    Parameters are those of :func:`optimal_wall`; the gradient is exact for each piece of the
    piecewise-linear area (the extreme crossing point of each strip moves with two wall nodes).

    Examples
    --------
    >>> f = wall_objective(positions=61, strips=3000)
    >>> area, grad = f(np.zeros(59))
    >>> round(area, 4), grad.shape
    (2.6503, (59,))
    """
    if objective not in ("exact", "positions"):
        raise InvalidPoints(f"unknown objective {objective!r}; use 'exact' or 'positions'")
    g = _Grid.make(l, positions, strips, THESIS_WALL_NODES * (l / 3.0), objective == "exact")

    def f(x: FloatArray) -> tuple[float, FloatArray]:
        area, grad = g.area_and_gradient(np.concatenate([[0.0], np.asarray(x, float), [0.0]]))
        return area, grad[1:-1]

    return f


# ------------------------------------------------------------------------------------------------
# arc grid and optimal wall
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ArcGrid:
    """Areas of the arc-wall family on a grid of centres ``(c, h)``.

    Attributes
    ----------
    c, h : (nc,), (nh,) grid values; area : (nh, nc); best : (c, h, area) of the minimum.
    """

    c: FloatArray
    h: FloatArray
    area: FloatArray
    best: tuple[float, float, float]


#: The thesis's arc grid (Fig. 6.11): centres c = -1.4..-0.6 and h = 2.0..2.4, step 0.1.
ARC_C = tuple(np.round(np.arange(-1.4, -0.55, 0.1), 10))
ARC_H = tuple(np.round(np.arange(2.0, 2.45, 0.1), 10))


def arc_grid(c: ArrayLike = ARC_C, h: ArrayLike = ARC_H, l: float = 3.0,
             positions: int = 4000, strips: int = 3000,
             progress: Callable[[int, int], None] | None = None) -> ArcGrid:
    """The circular-arc grid search of Fig. 6.11 (default grid c = -1.4..-0.6, h = 2.0..2.4).

    ``progress(done, total)``, if given, is called before each row of heights (``total`` rows);
    an exception it raises (a cancelled run) ends the search.

    Examples
    --------
    >>> g = arc_grid([-1.1, -1.0, -0.9], [2.2], positions=2000, strips=1500)
    >>> (round(g.best[0], 1), round(g.best[1], 1), round(g.best[2], 3))
    (-1.0, 2.2, 2.552)
    """
    cs, hs = np.round(np.asarray(c, float), 10), np.round(np.asarray(h, float), 10)
    area = np.empty((hs.size, cs.size))
    for j, hi in enumerate(hs):
        if progress is not None:
            progress(j, hs.size)
        area[j] = [strip_area(*wall_motion(arc_wall(ci, hi, l), l, positions), strips) for ci in cs]
    j, i = np.unravel_index(np.argmin(area), area.shape)
    return ArcGrid(cs, hs, area, (float(cs[i]), float(hs[j]), float(area[j, i])))


@dataclass(frozen=True)
class OptimalWall:
    """Result of :func:`optimal_wall`.

    Attributes
    ----------
    w : (61,) wall abscissae at :data:`THESIS_WALL_NODES` (ends 0; all >= :data:`WALL_LOWER_BOUND`).
    area_grid : the objective at the optimum (its own ``grid`` positions x strips and quadrature).
    area : the converged exact area of the wall (strip formula with A's path, ``final`` grid; agrees
        with the polygon union to < 1e-6).
    area_positions : the same wall by the positions-only quadrature on ``final`` (what §6 of the
        spec reports as 2.4995).
    area_thesis : positions-only quadrature with ``thesis_positions`` positions (the thesis's
        discretisation, which produced its 2.486).
    start_area : area of the vertical starting wall on ``final`` (3 pi l^2 / 32).
    method, objective : solver and quadrature optimised (``"exact"`` or ``"positions"``).
    iterations, evaluations : solver iterations and area evaluations (each with its gradient).
    seconds : solver time (without the final evaluations).
    grid, final : (positions, strips); thesis_positions : positions of ``area_thesis``.
    """

    w: FloatArray
    area_grid: float
    area: float
    area_positions: float
    area_thesis: float
    start_area: float
    method: str
    objective: str
    iterations: int
    evaluations: int
    seconds: float
    grid: tuple[int, int]
    final: tuple[int, int]
    thesis_positions: int


def _descent_gradient(g: FloatArray, x: FloatArray) -> FloatArray:
    """The gradient without the components the lower bound stops (at the bound, the area rising with x)."""
    return np.where((x <= WALL_LOWER_BOUND) & (g > 0.0), 0.0, g)


def _fletcher_reeves(f: Callable[[FloatArray], tuple[float, FloatArray]], x0: FloatArray, maxiter: int,
                     gtol: float) -> tuple[FloatArray, int]:
    """Fletcher-Reeves conjugate gradients with a Brent line search, restarted every n steps, on ``x >= 0``.

    The thesis's method, kept to the bound by projection (each trial point is ``max(x + t d, 0)``)
    and by dropping the gradient components the bound stops (see :data:`WALL_LOWER_BOUND`).
    """
    x = np.maximum(x0, WALL_LOWER_BOUND)
    fx, g = f(x)
    g = _descent_gradient(g, x)
    d = -g
    it = 0
    for it in range(1, maxiter + 1):
        if not np.dot(g, d) < 0:
            d = -g                                                     # not a descent direction: restart
        dn = np.abs(d).max()
        if dn == 0:
            break
        res = minimize_scalar(lambda t, x=x, d=d: f(np.maximum(x + t * d, WALL_LOWER_BOUND))[0], bounds=(0.0, 0.2 / dn),
                              method="bounded", options={"xatol": 1e-6 / dn})
        if not res.fun < fx:
            if np.array_equal(d, -g):
                break
            d = -g
            continue
        x = np.maximum(x + res.x * d, WALL_LOWER_BOUND)
        fx, g_new = f(x)
        g_new = _descent_gradient(g_new, x)
        if np.linalg.norm(g_new) < gtol:
            break
        beta = np.dot(g_new, g_new) / np.dot(g, g)
        d = -g_new + (beta * d if it % len(x) else 0.0)
        g = g_new
    return x, it


def optimal_wall(method: Literal["lbfgsb", "fletcher_reeves"] = "lbfgsb", l: float = 3.0,
                 grid: tuple[int, int] = (400, 1000), final: tuple[int, int] = (6000, 5000),
                 objective: Literal["exact", "positions"] = "exact", thesis_positions: int = 361,
                 maxiter: int = 400, gtol: float = 1e-7, start: ArrayLike | None = None,
                 progress: Callable[[int], None] | None = None) -> OptimalWall:
    """Minimise the swept area over the 59 wall abscissae of Fig. 6.12 (§6).

    The objective is the strip-formula area on ``grid`` (positions, strips); its gradient is exact
    piecewise (each strip's extreme crossing points move with two wall nodes), so no numerical
    differentiation is needed (the thesis differentiated numerically: 32 756 area calls, 50 h).
    Both solvers keep the wall right of the y axis (:data:`WALL_LOWER_BOUND`), which loses no optimum.
    The optimum is re-evaluated on ``final`` with the exact quadrature (``area``), with the
    positions-only quadrature (``area_positions``) and with the thesis's discretisation
    (``area_thesis``, positions only, ``thesis_positions`` positions).

    Parameters
    ----------
    method : ``"lbfgsb"`` (scipy L-BFGS-B, with the bound) or ``"fletcher_reeves"`` (the thesis's
        method: nonlinear conjugate gradients, Fletcher-Reeves update, line search, restart every 59
        steps; projected onto the bound).
    l : rod length (the thesis: 3).
    grid, final : (positions, strips) of the optimisation and of the final evaluation.
    objective : ``"exact"`` (strip formula with A's path crossing, converged to O(1/positions^2))
        or ``"positions"`` (sampled positions only, as the thesis and spec §6 did; the optimiser
        then exploits that quadrature's low bias on bulged walls).
    thesis_positions : positions of the thesis-like evaluation.
    maxiter, gtol : iteration limit and gradient-norm tolerance.
    start : initial inner abscissae (59; negative ones start at 0); default the vertical wall (area
        3 pi l^2 / 32).
    progress : called as ``progress(evaluations)`` before each evaluation of the objective; an
        exception it raises (a cancelled run) ends the optimisation.

    Returns
    -------
    OptimalWall
    """
    objective_fn = wall_objective(l, grid[0], grid[1], objective)
    calls = 0

    def f(x: FloatArray) -> tuple[float, FloatArray]:
        nonlocal calls
        if progress is not None:
            progress(calls)
        calls += 1
        return objective_fn(x)

    x0 = np.zeros(len(THESIS_WALL_NODES) - 2) if start is None else np.asarray(start, float).ravel()
    t0 = time.perf_counter()
    if method == "lbfgsb":
        res = minimize(f, x0, jac=True, method="L-BFGS-B", bounds=[(WALL_LOWER_BOUND, None)] * len(x0),
                       options={"maxiter": maxiter, "gtol": gtol, "maxcor": 30})
        x, iterations = res.x, int(res.nit)
    elif method == "fletcher_reeves":
        x, iterations = _fletcher_reeves(f, x0, maxiter, gtol)
    else:
        raise InvalidPoints(f"unknown method {method!r}; use 'lbfgsb' or 'fletcher_reeves'")
    seconds = time.perf_counter() - t0
    w = np.concatenate([[0.0], x, [0.0]])
    return OptimalWall(w, f(x)[0], wall_area(w, l, *final), wall_area(w, l, *final, path=False),
                       wall_area(w, l, thesis_positions, final[1], path=False), wall_area(np.zeros_like(w), l, *final),
                       method, objective, iterations, calls, seconds, grid, final, thesis_positions)
