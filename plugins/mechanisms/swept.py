"""Area swept by a moving segment (``analysis.md`` §5.1-§5.2 and §7).

A rod AB is given by its end positions ``a``, ``b`` at successive instants (``(T, 2)`` in the plane,
``(T, 3)`` in space, mm); units of area are the square of the input unit.

* :func:`segment_swept_area` — planar: ``"exact"`` is the union of the quadrilaterals between
  successive positions (shapely), with a bow-tie (successive rods crossing) split into the two
  triangles meeting at the crossing point, never its convex hull; ``"raster"`` is the thesis's
  display device (§6.2.1): each position drawn by DDA on a 256 x 256 grid, area = marked pixels.
* :func:`strip_area` — the exact strip formula for the constrained motion of §5 (B on the x axis,
  A descending): ``S = int [X_max(y) - X_min(y)] dy``.
* :func:`spatial_swept_area` — the ruled surface in space by the thesis's two triangles per step
  (Fig. 6.15), crossing rods detected and reported, or by bilinear patches (Gauss quadrature), or
  (coplanar motions) the exact planar union.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import shapely
from numpy.typing import ArrayLike, NDArray

from .errors import DegenerateGeometry, InvalidPoints

__all__ = ["SpatialSweep", "segment_swept_area", "spatial_swept_area", "strip_area", "swept_region"]

FloatArray = NDArray[np.float64]


def _ends(a: ArrayLike, b: ArrayLike, dim: int | tuple[int, ...]) -> tuple[FloatArray, FloatArray]:
    A, B = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    dims = (dim,) if isinstance(dim, int) else dim
    for name, v in (("a", A), ("b", B)):
        if v.ndim != 2 or v.shape[1] not in dims:
            want = " or ".join(f"(T, {d})" for d in dims)
            raise InvalidPoints(f"rod end {name} must be positions of shape {want} mm, got {v.shape}")
    if A.shape != B.shape:
        raise InvalidPoints(f"rod ends a {A.shape} and b {B.shape} must have the same shape")
    bad = ~(np.isfinite(A).all(1) & np.isfinite(B).all(1))
    if bad.any():
        raise InvalidPoints(f"rod end positions must be finite; frame {int(np.flatnonzero(bad)[0])} has NaN "
                            "(fill or drop missing frames first)")
    if len(A) < 2:
        raise InvalidPoints(f"a swept area needs at least 2 positions, got {len(A)}")
    return A, B


def _cross2(u: FloatArray, v: FloatArray) -> FloatArray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def _segment_crossing(p: FloatArray, p2: FloatArray, q: FloatArray, q2: FloatArray) -> tuple[NDArray[np.bool_],
                                                                                          FloatArray]:
    """Whether segments p-p2 and q-q2 cross in their interiors (per row), and where (2-D)."""
    r, s = p2 - p, q2 - q
    den = _cross2(r, s)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = _cross2(q - p, s) / den
        u = _cross2(q - p, r) / den
    hit = (np.abs(den) > 1e-15 * (np.abs(r).sum(-1) * np.abs(s).sum(-1))) & (t > 0) & (t < 1) & (u > 0) & (u < 1)
    return hit, p + np.where(hit, t, 0.0)[:, None] * r


def swept_region(a: ArrayLike, b: ArrayLike) -> shapely.Geometry:
    """The region swept by a planar segment: union of the pieces between successive positions.

    Each step is the quadrilateral ``a_i b_i b_{i+1} a_{i+1}``; when it is a bow-tie (the rods
    cross, or the end paths cross) it is the two triangles meeting at the crossing point.

    Parameters
    ----------
    a, b : (T, 2) end positions, mm.

    Returns
    -------
    shapely.Geometry
        The swept region (Polygon or MultiPolygon), mm.
    """
    A, B = _ends(a, b, 2)
    a0, b0, a1, b1 = A[:-1], B[:-1], A[1:], B[1:]
    rods, x_rods = _segment_crossing(a0, b0, a1, b1)          # rod i crosses rod i+1
    paths, x_paths = _segment_crossing(a0, a1, b0, b1)        # end paths cross
    quads = ~(rods | paths)
    pieces = [shapely.polygons(np.stack([a0, b0, b1, a1], 1)[quads])]
    if rods.any():
        pieces += [shapely.polygons(np.stack([a0, x_rods, a1], 1)[rods]),
                   shapely.polygons(np.stack([b0, x_rods, b1], 1)[rods])]
    if paths.any():
        pieces += [shapely.polygons(np.stack([a0, b0, x_paths], 1)[paths]),
                   shapely.polygons(np.stack([a1, b1, x_paths], 1)[paths])]
    polys = np.concatenate(pieces)
    # A fixed precision grid (1e-10 of the extent) makes GEOS robust where many pieces share a
    # crossing point computed with round-off: the floating union lost 0.25 % of a turning rod's area.
    scale = float(np.abs(np.concatenate([A, B])).max()) or 1.0
    return shapely.union_all(shapely.make_valid(polys[shapely.area(polys) > 0]), grid_size=1e-10 * scale)


def _dda_raster(A: FloatArray, B: FloatArray, pixel: float, max_step: float) -> tuple[NDArray[np.bool_], float]:
    """Mark the pixels of every segment A_k B_k drawn by DDA (after densifying the motion)."""
    step = np.maximum(np.linalg.norm(np.diff(A, axis=0), axis=1), np.linalg.norm(np.diff(B, axis=0), axis=1))
    sub = np.maximum(1, np.ceil(step / (max_step * pixel))).astype(int)
    frac = np.concatenate([np.arange(n) / n + k for k, n in enumerate(sub)] + [[len(sub)]])
    idx = np.minimum(frac.astype(int), len(A) - 2)
    w = (frac - idx)[:, None]
    A2 = A[idx] * (1 - w) + A[idx + 1] * w
    B2 = B[idx] * (1 - w) + B[idx + 1] * w
    lo = np.minimum(A2.min(0), B2.min(0))
    pa, pb = (A2 - lo) / pixel, (B2 - lo) / pixel
    n = np.ceil(np.abs(pb - pa).max(1)).astype(int) + 1          # DDA: one sample per pixel of the major axis
    seg = np.repeat(np.arange(len(pa)), n)
    t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(np.maximum(n - 1, 1), n)
    pts = np.rint(pa[seg] + (pb[seg] - pa[seg]) * t[:, None]).astype(np.int64)
    shape = pts.max(0) + 1
    grid = np.zeros(shape, dtype=bool)
    grid[pts[:, 0], pts[:, 1]] = True
    return grid, pixel


def segment_swept_area(a: ArrayLike, b: ArrayLike, method: Literal["exact", "raster"] = "exact", *,
                       resolution: int = 256, pixel: float | None = None, max_step: float = 0.5) -> float:
    """Area swept by a planar segment moving through the positions ``(a_k, b_k)``.

    Parameters
    ----------
    a, b : (T, 2) end positions, mm (in motion order).
    method : ``"exact"`` — union of the regions between successive positions (converges from below
        as positions are added: -4e-4 relative on the astroid with 50 positions, -1e-6 with 1000);
        ``"raster"`` — the thesis's device: positions drawn by DDA into a pixel grid, area = number
        of marked pixels x pixel area (a boundary layer: about +4 % on the astroid when the rod
        spans 170 px, falling as 1/resolution).
    resolution : raster: pixels across the larger side of the motion's bounding box (the thesis's
        display had 256); ignored when ``pixel`` is given.
    pixel : raster: pixel size, mm.
    max_step : raster: the motion is densified so that no end moves more than this many pixels
        between drawn positions (the device sampled its encoders continuously).

    Returns
    -------
    float
        Area, mm².

    Raises
    ------
    InvalidPoints
        Shapes differ or are not (T, 2); NaN positions; fewer than 2 positions.

    Examples
    --------
    >>> phi = np.linspace(0, np.pi / 2, 1000)
    >>> a = np.stack([0 * phi, 3 * np.cos(phi)], -1)          # astroid motion, l = 3
    >>> b = np.stack([-3 * np.sin(phi), 0 * phi], -1)
    >>> round(segment_swept_area(a, b) / (3 * np.pi * 9 / 32), 5)
    1.0
    """
    A, B = _ends(a, b, 2)
    if method == "exact":
        return float(swept_region(A, B).area)
    if method == "raster":
        if pixel is None:
            span = np.ptp(np.concatenate([A, B]), axis=0).max()
            if not span > 0:
                raise DegenerateGeometry("the segment does not move or has zero length: nothing to rasterise")
            pixel = float(span) / (resolution - 1)
        grid, px = _dda_raster(A, B, float(pixel), max_step)
        return float(grid.sum()) * px * px
    raise InvalidPoints(f"unknown method {method!r}; use 'exact' or 'raster'")


def strip_area(a: ArrayLike, b: ArrayLike, strips: int = 2000, chunk: int = 256, path: bool = True) -> float:
    """Exact strip formula for the constrained motion of §5.2 (B on the x axis, A above it).

    ``S = int_0^{max A_y} [X_max(y) - X_min(y)] dy`` with ``X(t, y) = B_x + (A_x - B_x) y / A_y`` over
    the positions with ``A_y >= y`` (midpoint rule on ``strips`` strips). Exact for a motion whose
    positions crossing each height form one interval of time (A_y monotone), because the covered
    part of each horizontal line is then the interval between its extreme crossing points.

    The extreme crossing point at height ``y`` is often the end A itself, at the instant A passes
    that height, which no sampled position hits: the sampled positions just above ``y`` miss it by
    O(1 / positions), a bias that bulged walls make large (-0.2 % at 4000 positions for the optimal
    wall). The crossing of A's path (interpolated between the positions straddling ``y``) is
    therefore added as a candidate (``path=True``), leaving an O(1 / positions^2) error; without it
    (``path=False``) this is the positions-only quadrature the thesis's numbers are consistent with.

    Parameters
    ----------
    a, b : (T, 2) end positions, mm; ``b[:, 1]`` must be 0, ``a[:, 1] >= 0`` and monotone.
    strips : number of horizontal strips.
    chunk : strips evaluated at once (memory ``chunk x T``).
    path : include the crossing of A's interpolated path (default; ``False``: sampled positions only).

    Returns
    -------
    float
        Area, mm².

    Raises
    ------
    InvalidPoints
        B leaves the x axis, A goes below it, or A's height is not monotone.

    Examples
    --------
    >>> phi = np.linspace(0, np.pi / 2, 1500)
    >>> a = np.stack([0 * phi, 3 * np.cos(phi)], -1)
    >>> b = np.stack([-3 * np.sin(phi), 0 * phi], -1)
    >>> round(strip_area(a, b, 4000), 5)
    2.65072
    """
    A, B = _ends(a, b, 2)
    scale = np.abs(np.concatenate([A, B])).max()
    if np.abs(B[:, 1]).max() > 1e-12 * scale or A[:, 1].min() < -1e-12 * scale:
        raise InvalidPoints("strip_area needs B on the x axis (b[:, 1] = 0) and A above it (a[:, 1] >= 0); "
                            "use segment_swept_area for general motions")
    step = np.diff(A[:, 1])
    if not (np.all(step <= 0) or np.all(step >= 0)):
        k = int(np.flatnonzero(np.sign(step) != np.sign(step[np.flatnonzero(step)[0]]))[0])
        raise InvalidPoints(f"strip_area needs A's height monotone; it turns back at position {k + 1} "
                            "(use segment_swept_area)")
    order = np.argsort(A[:, 1], kind="stable")
    top = A[:, 1].max()
    dy = top / strips
    y = (np.arange(strips) + 0.5) * dy
    a_path = np.interp(y, A[order, 1], A[order, 0])          # A's own crossing of each height
    if not path:
        a_path = np.full_like(y, np.nan)
    total = 0.0
    with np.errstate(invalid="ignore", divide="ignore"):
        slope = (A[:, 0] - B[:, 0]) / A[:, 1]
    for s in range(0, strips, chunk):
        yy = y[s:s + chunk, None]
        X = B[None, :, 0] + slope[None] * yy
        inside = A[None, :, 1] >= yy
        hi = np.fmax(np.where(inside, X, -np.inf).max(1), a_path[s:s + chunk])
        lo = np.fmin(np.where(inside, X, np.inf).min(1), a_path[s:s + chunk])
        total += float(np.where(np.isfinite(hi - lo), hi - lo, 0.0).sum())
    return float(total * dy)


@dataclass(frozen=True)
class SpatialSweep:
    """Area swept by a rod in space.

    Attributes
    ----------
    area : total, mm².
    steps : (T-1,) area of each step between successive positions, mm².
    crossings : indices ``i`` where rod ``i`` and rod ``i+1`` cross (the triangle split folds over
        and double-counts there, Fig. 6.15 b).
    crossing_points : (len(crossings), 3) midpoints of the closest approach of the crossing rods, mm.
    method : ``"triangles"``, ``"bilinear"`` or ``"union"``.
    """

    area: float
    steps: FloatArray
    crossings: NDArray[np.int64]
    crossing_points: FloatArray
    method: str


def _crossings(A: FloatArray, B: FloatArray) -> tuple[NDArray[np.int64], FloatArray, FloatArray]:
    """Steps whose quadrilateral folds over: the two triangles' normals point opposite ways."""
    a0, b0, a1, b1 = A[:-1], B[:-1], A[1:], B[1:]
    n1 = np.cross(b0 - a0, b1 - a0)
    n2 = np.cross(b1 - a0, a1 - a0)
    scale = np.linalg.norm(n1, axis=-1) * np.linalg.norm(n2, axis=-1)
    folded = np.einsum("ij,ij->i", n1, n2) < -1e-12 * np.maximum(scale, 1e-300)
    idx = np.flatnonzero(folded)
    # closest points of the lines a0-b0 and a1-b1
    u, v, w = b0[idx] - a0[idx], b1[idx] - a1[idx], a0[idx] - a1[idx]
    uu, uv, vv = (u * u).sum(1), (u * v).sum(1), (v * v).sum(1)
    uw, vw = (u * w).sum(1), (v * w).sum(1)
    den = uu * vv - uv**2
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.clip((uv * vw - vv * uw) / den, 0, 1)
        t = np.clip((uu * vw - uv * uw) / den, 0, 1)
    pts = 0.5 * ((a0[idx] + s[:, None] * u) + (a1[idx] + t[:, None] * v))
    return idx.astype(np.int64), pts, s


def _bilinear_areas(A: FloatArray, B: FloatArray, order: int, split: FloatArray) -> FloatArray:
    """Area of each bilinear patch P(u, v) between successive rods by Gauss-Legendre quadrature.

    The u direction is split at ``split`` (per step): where rods cross, the patch folds along the
    crossing and the integrand has a kink there, which a single Gauss rule converges to slowly.
    """
    x, wq = np.polynomial.legendre.leggauss(order)
    x, wq = 0.5 * (x + 1), 0.5 * wq
    sp = split[:, None]
    u = np.concatenate([sp * x, sp + (1 - sp) * x], 1)[:, :, None, None]          # (S, 2n, 1, 1)
    wu = np.concatenate([sp * wq, (1 - sp) * wq], 1)                                # (S, 2n)
    a0, b0, a1, b1 = (q[:, None, None, :] for q in (A[:-1], B[:-1], A[1:], B[1:]))
    v = x[None, None, :, None]
    du = (1 - v) * (b0 - a0) + v * (b1 - a1)
    dv = (1 - u) * (a1 - a0) + u * (b1 - b0)
    return np.einsum("tuv,tu,v->t", np.linalg.norm(np.cross(du, dv), axis=-1), wu, wq)


def spatial_swept_area(a: ArrayLike, b: ArrayLike, method: Literal["triangles", "bilinear", "union"] = "triangles",
                       *, order: int = 8) -> SpatialSweep:
    """Area swept by a rod in space (``analysis.md`` §7, thesis Fig. 6.15).

    Parameters
    ----------
    a, b : (T, 3) end positions, mm.
    method : ``"triangles"`` (thesis, default): each quadrilateral ``A_i B_i B_{i+1} A_{i+1}`` split
        into the triangles ``A_i B_i B_{i+1}`` and ``A_i B_{i+1} A_{i+1}``; it measures the ruled
        surface (re-swept parts count again) and double-counts where successive rods cross
        (reported in ``crossings``; e.g. 2x the true area for a rod turning about its middle).
        ``"bilinear"``: area of the bilinear patch of each step (Gauss-Legendre, ``order`` points
        per direction), which stays right through crossings. ``"union"``: for a motion in one
        plane only, the exact planar union (:func:`swept_region`) in that plane.
    order : bilinear: Gauss points per direction (and per side of a crossing).

    Returns
    -------
    SpatialSweep
        ``.area`` mm², per-step areas, crossing steps and points.

    Raises
    ------
    InvalidPoints
        Not (T, 3) or NaN; ``"union"`` for a motion that leaves a plane.

    Examples
    --------
    >>> ang = np.linspace(0, np.pi / 2, 41)
    >>> d = 150 * np.stack([np.cos(ang), np.sin(ang), 0 * ang], -1)     # 300 mm rod turned about its centre
    >>> s = spatial_swept_area(-d, d)
    >>> round(s.area / (np.pi * 300**2 / 8), 2), len(s.crossings)
    (2.0, 40)
    >>> round(spatial_swept_area(-d, d, "bilinear").area / (np.pi * 300**2 / 8), 4)
    0.9997
    """
    A, B = _ends(a, b, 3)
    crossings, points, where = _crossings(A, B)
    if method == "triangles":
        a0, b0, a1, b1 = A[:-1], B[:-1], A[1:], B[1:]
        steps = 0.5 * (np.linalg.norm(np.cross(b0 - a0, b1 - a0), axis=-1)
                       + np.linalg.norm(np.cross(b1 - a0, a1 - a0), axis=-1))
    elif method == "bilinear":
        split = np.full(len(A) - 1, 0.5)
        split[crossings] = np.clip(where, 1e-3, 1 - 1e-3)
        steps = _bilinear_areas(A, B, order, split)
    elif method == "union":
        P = np.concatenate([A, B])
        c = P.mean(0)
        _, sv, vt = np.linalg.svd(P - c, full_matrices=False)
        if sv[2] > 1e-9 * max(sv[0], 1e-300):
            raise InvalidPoints(f"method 'union' needs a motion in one plane; the rod leaves it by "
                                f"{sv[2] / np.sqrt(len(P)):.3g} mm RMS (use 'triangles' or 'bilinear')")
        region = swept_region((A - c) @ vt[:2].T, (B - c) @ vt[:2].T)
        return SpatialSweep(float(region.area), np.full(len(A) - 1, np.nan), crossings, points, "union")
    else:
        raise InvalidPoints(f"unknown method {method!r}; use 'triangles', 'bilinear' or 'union'")
    return SpatialSweep(float(steps.sum()), steps, crossings, points, method)
