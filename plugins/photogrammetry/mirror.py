"""Mirror method: a plane mirror as a second (virtual) camera (thesis §3.2, spec §6–§7, §9).

One camera at :math:`\\mathbf F_1` sees each marker directly (ray :math:`\\hat u_1`) and in a plane
mirror (ray :math:`\\hat u_2'` toward the virtual image). Reflecting the camera and the mirror ray
in the mirror plane gives a virtual camera :math:`\\mathbf F_2` with ray :math:`\\hat u_2 = M\\hat u_2'`
toward the real marker; the marker is where the two rays (nearly) meet.

Conventions (spec §0, §6.1): lengths in mm, angles in rad, one right-handed world frame for all
points, centres, rays and normals. The mirror plane is given by any point ``mirror_point``
(:math:`\\mathbf G`) on the silvered surface and its unit normal ``normal`` (:math:`\\hat n`),
oriented toward the reflecting side, i.e. toward the camera: :math:`(\\mathbf G-\\mathbf F_1)\\cdot
\\hat n<0` (3.10). The reflection :math:`M = I - 2\\hat n\\hat n^T` (3.12) has determinant −1, which
is why it is kept as a matrix and never as a rotation vector.

Functions are vectorised over markers: rays are ``(N, 3)`` arrays; no Python loop runs over N.
Degenerate markers raise :class:`~mirrorlab.plugins.photogrammetry.errors.DegenerateGeometry`
naming the marker indices (or, with ``on_degenerate="flag"``, are reported in a mask and set to NaN).
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Literal, Protocol

import numpy as np
import scipy.sparse
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from .errors import DegenerateGeometry

__all__ = [
    "MirrorNormal",
    "VirtualCamera",
    "RayIntersection",
    "MirrorTriangulation",
    "ProjectingCamera",
    "mirror_normal",
    "reflection_matrix",
    "reflect",
    "virtual_camera",
    "intersect_rays",
    "triangulate_mirror",
    "triangulate_mirrors",
]

FloatArray = NDArray[np.float64]
OnDegenerate = Literal["raise", "flag"]

#: Suggested thresholds of the spec (§6.3, §7); all are keyword arguments of the functions.
PARALLEL_TOL = 1e-12  # on 1 - k^2, k = cos(angle between the rays)
PAIR_TOL = 1e-6  # on |A_k| and on the spread of the A_k (mirror normal)
MIN_ANGLE = np.deg2rad(2.0)  # weak-geometry flag


class ProjectingCamera(Protocol):
    """What ``method="optimal"`` needs of a camera model (e.g. ``PinholeCamera``)."""

    camera_center: ArrayLike

    def project(self, points: FloatArray) -> FloatArray:
        """World points (N, 3) mm -> image points (N, 2) px."""

    def rays(self, xy: FloatArray) -> FloatArray:
        """Image points (N, 2) px -> world ray directions (N, 3)."""


# --------------------------------------------------------------------------- helpers


def _dot(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.einsum("...i,...i->...", a, b)


def _unit(v: FloatArray) -> FloatArray:
    return v / np.sqrt(_dot(v, v))[..., None]


def _vec3(x: ArrayLike, name: str) -> FloatArray:
    a = np.asarray(x, dtype=np.float64)
    if a.shape != (3,) or not np.all(np.isfinite(a)):
        raise ValueError(f"{name} must be a finite 3-vector in mm, got shape {a.shape}: {a!r}")
    return a


def _rays(x: ArrayLike, name: str) -> FloatArray:
    a = np.asarray(x, dtype=np.float64)
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name} must have shape (N, 3), got {a.shape}")
    return a


def _index_list(idx: NDArray[np.intp], limit: int = 8) -> str:
    shown = ", ".join(str(int(i)) for i in idx[:limit])
    more = f" and {idx.size - limit} more" if idx.size > limit else ""
    return f"marker{'s' if idx.size > 1 else ''} {shown}{more}"


def _unit_normal(normal: ArrayLike) -> FloatArray:
    n = _vec3(normal, "normal")
    norm = float(np.linalg.norm(n))
    if norm < 1e-12:
        raise DegenerateGeometry("mirror normal has zero length; check the mirror_normal() result")
    return n / norm


def _check_orientation(camera_center: FloatArray, mirror_point: FloatArray, n: FloatArray) -> float:
    """Signed distance of the camera from the mirror (> 0 on the reflecting side), eq. (3.10)."""
    s = float(_dot(camera_center - mirror_point, n))
    if abs(s) < 1e-9 * max(1.0, float(np.linalg.norm(camera_center - mirror_point))):
        raise DegenerateGeometry(
            "camera lies in the mirror plane ((G - F1)·n = 0): check mirror_point and camera_center"
        )
    if s < 0:
        raise DegenerateGeometry(
            f"mirror normal points away from the camera ((G - F1)·n = {-s:.6g} mm > 0 violates eq. 3.10): "
            "flip the normal, or check mirror_point / camera_center"
        )
    return s


# --------------------------------------------------------------------------- mirror normal


@dataclass(frozen=True)
class MirrorNormal:
    """Mirror normal from marker/mirror-image ray pairs (eqs 3.8–3.10).

    Attributes
    ----------
    normal : (3,) unit normal, oriented toward the camera (reflecting side).
    residual : RMS of :math:`\\hat A_k\\cdot\\hat n` over the pairs, dimensionless (≈ rad): the
        sine of the angle by which the normal misses each pair's plane. 0 for exact data.
    n_pairs : number of pairs used.
    method : ``"lstsq"`` or ``"thesis"``.
    """

    normal: FloatArray
    residual: float
    n_pairs: int
    method: str

    def __iter__(self) -> Iterator[Any]:
        """Unpack as ``normal, residual = mirror_normal(...)``."""
        return iter((self.normal, self.residual))


def mirror_normal(
    real_rays: ArrayLike,
    virtual_rays: ArrayLike,
    *,
    mirror_point: ArrayLike | None = None,
    camera_center: ArrayLike | None = None,
    method: Literal["lstsq", "thesis"] = "lstsq",
    tol: float = PAIR_TOL,
) -> MirrorNormal:
    """Unit mirror normal from K ≥ 2 markers seen directly and in the mirror (eqs 3.8–3.10).

    Each pair spans a plane containing the normal, :math:`\\mathbf A_k=\\hat P_k\\times\\hat P_k'`
    (3.8). ``method="lstsq"`` (default, mirrorlab choice) takes the right singular vector of the
    smallest singular value of the stacked unit :math:`\\hat{\\mathbf A}_k` (least squares over all
    pairs; for K = 2 this is (3.9) exactly). ``method="thesis"`` is the Appendix 2 program:
    consecutive pairs form groups ``(0, 1), (2, 3), ...``, each gives
    :math:`\\mathbf n_g=\\mathbf A_2\\times\\mathbf A_1`, oriented, and the *unnormalised* ``n_g``
    are summed and normalised (K must be even).

    Parameters
    ----------
    real_rays, virtual_rays : (K, 3) array_like
        Directions from the camera centre to each marker and to its mirror image (any length).
    mirror_point, camera_center : (3,) array_like, optional, mm
        :math:`\\mathbf G` and :math:`\\mathbf F_1`. When both are given the normal is oriented by
        (3.10), :math:`(\\mathbf G-\\mathbf F_1)\\cdot\\hat n<0`; otherwise so that
        :math:`\\hat n\\cdot\\hat P_k'<0` (mirror rays travel against the normal).
    method : {"lstsq", "thesis"}
    tol : float
        Rejection threshold on :math:`|\\mathbf A_k|` and on the spread of the pair planes.

    Returns
    -------
    MirrorNormal
        ``normal`` (3,) and ``residual`` (dimensionless); unpacks as ``(normal, residual)``.

    Raises
    ------
    DegenerateGeometry
        Fewer than two pairs; a marker on the camera's own normal line to the mirror
        (:math:`|\\mathbf A_k|<\\tau`); all pair planes coplanar (no unique normal).

    Examples
    --------
    >>> import numpy as np
    >>> F1, G, n = np.zeros(3), np.array([0., 0., -1000.]), np.array([0., 0., 1.])
    >>> P = np.array([[100., 50., -300.], [-80., 120., -500.]])
    >>> Pv = P - 2 * ((P - G) @ n)[:, None] * n          # mirror images
    >>> res = mirror_normal(P - F1, Pv - F1, mirror_point=G, camera_center=F1)
    >>> np.allclose(res.normal, n), res.residual < 1e-12
    (True, True)
    """
    P = _unit(_rays(real_rays, "real_rays"))
    Pv = _unit(_rays(virtual_rays, "virtual_rays"))
    if P.shape != Pv.shape:
        raise ValueError(f"real_rays {P.shape} and virtual_rays {Pv.shape} must have the same shape")
    k = P.shape[0]
    if k < 2:
        raise DegenerateGeometry(
            f"mirror normal needs at least two marker/mirror-image pairs, got {k}: digitise more markers"
        )
    if not np.all(np.isfinite(P)) or not np.all(np.isfinite(Pv)):
        bad = np.flatnonzero(~(np.isfinite(P).all(1) & np.isfinite(Pv).all(1)))
        raise DegenerateGeometry(f"{_index_list(bad)}: ray is not finite (not seen?); drop the pair")
    A = np.cross(P, Pv)  # (3.8)
    a_norm = np.sqrt(_dot(A, A))
    bad = np.flatnonzero(a_norm < tol)
    if bad.size:
        raise DegenerateGeometry(
            f"{_index_list(bad)}: marker and mirror-image rays are parallel (|A_k| < {tol:g}); the marker "
            "is on the camera's normal line to the mirror or the correspondence is wrong; use other markers"
        )
    A_hat = A / a_norm[:, None]

    if mirror_point is not None and camera_center is not None:
        toward = _vec3(mirror_point, "mirror_point") - _vec3(camera_center, "camera_center")
    else:
        toward = Pv.sum(axis=0)  # the mirror side as seen from the camera

    if method == "lstsq":
        _, s, vt = np.linalg.svd(A_hat, full_matrices=False)
        if s[1] < tol * s[0]:
            raise DegenerateGeometry(
                f"all {k} marker/mirror-image pairs are coplanar with the mirror normal (|A_1 × A_2| ≈ 0): "
                "the normal is undetermined; use markers off the plane through the camera and the normal"
            )
        n = vt[-1] if vt.shape[0] == 3 else np.cross(vt[0], vt[1])
    elif method == "thesis":
        if k % 2:
            raise ValueError(f"method='thesis' uses groups of two pairs; got an odd number of pairs ({k})")
        A1, A2 = A[0::2], A[1::2]
        ng = np.cross(A2, A1)
        ng_norm = np.sqrt(_dot(ng, ng))
        bad = np.flatnonzero(ng_norm < tol * a_norm[0::2] * a_norm[1::2])
        if bad.size:
            raise DegenerateGeometry(
                f"{_index_list(2 * bad)} (with the next pair): the two pairs of the group are coplanar with the "
                "mirror normal (|A_1 × A_2| ≈ 0); regroup the markers"
            )
        ng = np.where((_dot(ng, toward) > 0)[:, None], -ng, ng)
        n = ng.sum(axis=0)
    else:
        raise ValueError(f"method must be 'lstsq' or 'thesis', got {method!r}")
    n = n / np.linalg.norm(n)
    side = float(_dot(toward, n))
    if side == 0.0:
        raise DegenerateGeometry("camera lies in the mirror plane ((G - F1)·n = 0): check mirror_point")
    if side > 0:  # (3.10)
        n = -n
    residual = float(np.sqrt(np.mean(_dot(A_hat, n) ** 2)))
    return MirrorNormal(normal=n, residual=residual, n_pairs=k, method=method)


# --------------------------------------------------------------------------- reflection


def reflection_matrix(mirror_point: ArrayLike, normal: ArrayLike) -> FloatArray:
    """4×4 homogeneous reflection in the plane through ``mirror_point`` with ``normal`` (det −1).

    :math:`\\mathbf x' = M\\mathbf x + 2(\\mathbf G\\cdot\\hat n)\\hat n`, with :math:`M` of (3.12).
    A projection matrix ``P`` of the real camera becomes ``P @ reflection_matrix(G, n)`` for the
    virtual camera (it maps a real marker to the pixel of its mirror image).

    Parameters
    ----------
    mirror_point : (3,) array_like, mm
    normal : (3,) array_like (normalised here)

    Returns
    -------
    (4, 4) ndarray, an involution with determinant −1.

    Examples
    --------
    >>> import numpy as np
    >>> H = reflection_matrix([0., 0., 10.], [0., 0., 1.])
    >>> H @ [1., 2., 3., 1.]
    array([ 1.,  2., 17.,  1.])
    >>> round(float(np.linalg.det(H)), 12)
    -1.0
    """
    n = _unit_normal(normal)
    G = _vec3(mirror_point, "mirror_point")
    H = np.eye(4)
    H[:3, :3] -= 2.0 * np.outer(n, n)
    H[:3, 3] = 2.0 * float(G @ n) * n
    return H


def reflect(
    points_or_vectors: ArrayLike,
    mirror_point: ArrayLike,
    normal: ArrayLike,
    *,
    vectors: bool = False,
) -> FloatArray:
    """Reflect points (or direction vectors) in a plane mirror (eqs 3.11–3.13).

    Parameters
    ----------
    points_or_vectors : (..., 3) array_like, mm
    mirror_point : (3,) array_like, mm
    normal : (3,) array_like (normalised here)
    vectors : bool
        ``True``: reflect directions, :math:`M\\mathbf v` (3.13), ignoring ``mirror_point``.
        ``False``: reflect points, :math:`\\mathbf x-2((\\mathbf x-\\mathbf G)\\cdot\\hat n)\\hat n`.

    Returns
    -------
    ndarray of the input's shape.

    Examples
    --------
    >>> reflect([[1., 2., 3.]], [0., 0., 10.], [0., 0., 1.])
    array([[ 1.,  2., 17.]])
    >>> reflect([[1., 2., 3.]], [0., 0., 10.], [0., 0., 1.], vectors=True)
    array([[ 1.,  2., -3.]])
    """
    n = _unit_normal(normal)
    x = np.asarray(points_or_vectors, dtype=np.float64)
    if x.shape[-1] != 3:
        raise ValueError(f"points_or_vectors must have shape (..., 3), got {x.shape}")
    s = _dot(x, n) if vectors else _dot(x - _vec3(mirror_point, "mirror_point"), n)
    return x - 2.0 * s[..., None] * n


@dataclass(frozen=True)
class VirtualCamera:
    """The mirror image of the camera (eqs 3.11–3.12).

    Attributes
    ----------
    center : (3,) :math:`\\mathbf F_2`, mm.
    matrix : (3, 3) :math:`M=I-2\\hat n\\hat n^T`, det −1.
    homogeneous : (4, 4) reflection in the mirror plane (see :func:`reflection_matrix`).
    distance : camera-to-mirror distance :math:`(\\mathbf F_1-\\mathbf G)\\cdot\\hat n>0`, mm.
    """

    center: FloatArray
    matrix: FloatArray
    homogeneous: FloatArray
    distance: float

    def __iter__(self) -> Iterator[Any]:
        """Unpack as ``F2, M = virtual_camera(...)``."""
        return iter((self.center, self.matrix))


def virtual_camera(camera_center: ArrayLike, mirror_point: ArrayLike, normal: ArrayLike) -> VirtualCamera:
    """Virtual camera :math:`\\mathbf F_2` and reflection :math:`M` (eqs 3.11–3.12).

    Parameters
    ----------
    camera_center : (3,) array_like, mm — :math:`\\mathbf F_1`.
    mirror_point : (3,) array_like, mm — :math:`\\mathbf G` on the reflecting surface.
    normal : (3,) array_like — mirror normal toward the camera (normalised here).

    Returns
    -------
    VirtualCamera
        Unpacks as ``(F2, M)``.

    Raises
    ------
    DegenerateGeometry
        The normal violates (3.10) or the camera lies in the mirror plane.

    Examples
    --------
    >>> F2, M = virtual_camera([0., 0., 0.], [0., 0., -500.], [0., 0., 1.])
    >>> F2
    array([    0.,     0., -1000.])
    """
    F1 = _vec3(camera_center, "camera_center")
    G = _vec3(mirror_point, "mirror_point")
    n = _unit_normal(normal)
    dist = _check_orientation(F1, G, n)
    F2 = F1 - 2.0 * dist * n  # (3.11)
    M = np.eye(3) - 2.0 * np.outer(n, n)  # (3.12)
    return VirtualCamera(center=F2, matrix=M, homogeneous=reflection_matrix(G, n), distance=dist)


# --------------------------------------------------------------------------- ray intersection

_CHUNK = 8192  # markers per block of the two-ray kernel (keeps the temporaries in cache)


@dataclass(frozen=True)
class RayIntersection:
    """Least-squares intersection of several rays per point.

    Attributes
    ----------
    points : (N, 3) mm, the point minimising the sum of squared distances to the rays.
    residual : (N,) mm, RMS perpendicular distance of the point from its rays (for two rays,
        half the miss distance).
    depths : (N, V) mm, distance along each ray to the foot of the perpendicular from the point
        (the thesis :math:`a_1, a_2` for two rays); NaN for views that do not see the point.
    n_views : (N,) number of rays used.
    cos_angle : (N,) :math:`|\\cos|` of the largest angle between two of the point's rays.
    degenerate : (N,) bool, points that failed a check (only with ``on_degenerate="flag"``).
    """

    points: FloatArray
    residual: FloatArray
    depths: FloatArray
    n_views: NDArray[np.intp]
    cos_angle: FloatArray
    degenerate: NDArray[np.bool_]

    @property
    def angle(self) -> FloatArray:
        """(N,) rad, largest intersection angle between two rays, :math:`\\arccos|\\cos|` (computed on access)."""
        return np.arccos(np.minimum(self.cos_angle, 1.0))


def _reject(mask: NDArray[np.bool_], message: str, on_degenerate: OnDegenerate) -> None:
    if on_degenerate == "raise" and mask.any():
        raise DegenerateGeometry(f"{_index_list(np.flatnonzero(mask))}: {message}")


_PARALLEL_MSG = ("rays are parallel (1 - k² < {tol:g}): the marker lies on the line through the two camera "
                 "centres (for a mirror: on its normal through the camera), or the correspondence is wrong")
_BEHIND_MSG = ("closest approach lies behind a camera (depth ≤ 0): wrong correspondence, or a wrong mirror "
               "normal orientation / mirror point")


def _two_rays(
    o1: FloatArray, o2: FloatArray, d1: FloatArray, d2: FloatArray, n2: FloatArray | None
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Closest approach of ``o1 + s d1`` and ``o2 + t M d2`` (M = reflection in normal ``n2``, or I).

    Eqs (3.2)–(3.7) for directions of any length (the unit-vector forms multiplied through), evaluated
    coordinate-wise in cache-sized blocks of markers. Returns points (N, 3), miss distance (N,),
    depths (N, 2), 1 - k² (N,) and |k| (N,), with k the cosine between the rays.
    """
    n_pts = d1.shape[0]
    nv = np.zeros(3) if n2 is None else n2
    out = np.empty((8, n_pts))  # x, y, z, miss distance, a1, a2, 1 - k², |k|
    per_point = o1.ndim == 2 or o2.ndim == 2
    if per_point:
        O1 = np.ascontiguousarray(np.broadcast_to(o1, d1.shape).T)
        O2 = np.ascontiguousarray(np.broadcast_to(o2, d1.shape).T)
    else:
        D = o2 - o1
        MD = D - 2.0 * (D @ nv) * nv  # u2·D = u2'·(M D)
        mid, diff = 0.5 * (o1 + o2), o1 - o2
    for lo in range(0, n_pts, _CHUNK):  # blocks of markers, not a loop over markers
        sl = slice(lo, lo + _CHUNK)
        if per_point:
            D = O2[:, sl] - O1[:, sl]
            MD = D - 2.0 * np.outer(nv, nv @ D)
            mid, diff = 0.5 * (O1[:, sl] + O2[:, sl]), O1[:, sl] - O2[:, sl]
        U1, U2 = d1[sl].T.copy(), d2[sl].T.copy()  # (3, chunk), contiguous rows
        x1, y1, z1 = U1
        x2, y2, z2 = U2
        a = x1 * x1 + y1 * y1 + z1 * z1
        c = x2 * x2 + y2 * y2 + z2 * z2  # |M u2| = |u2|
        w = nv[0] * x2 + nv[1] * y2 + nv[2] * z2
        b = x1 * x2 + y1 * y2 + z1 * z2 - 2.0 * (nv[0] * x1 + nv[1] * y1 + nv[2] * z1) * w  # u1·(M u2)
        e = D[0] * x1 + D[1] * y1 + D[2] * z1
        f = MD[0] * x2 + MD[1] * y2 + MD[2] * z2
        ac = a * c
        den = ac - b * b  # |u1|²|u2|²(1 - k²)
        inv = 1.0 / den
        s = (c * e - b * f) * inv  # (3.5) / |u1|
        t = (b * e - a * f) * inv  # (3.6) / |u2|
        hs, ht, tw = 0.5 * s, 0.5 * t, t * w
        o = out[:, sl]
        g2 = np.zeros_like(s)
        for i in range(3):  # the three coordinates
            o[i] = mid[i] + hs * U1[i] + ht * U2[i] - tw * nv[i]  # (3.7)
            gi = diff[i] + s * U1[i] - t * U2[i] + (2.0 * nv[i]) * tw  # V1 - V2
            g2 += gi * gi
        np.sqrt(g2, out=o[3])
        np.multiply(s, np.sqrt(a), out=o[4])
        np.multiply(t, np.sqrt(c), out=o[5])
        np.divide(den, ac, out=o[6])
        np.divide(np.abs(b), np.sqrt(ac), out=o[7])
    return out[:3].T, out[3], out[4:6].T, out[6], out[7]


def intersect_rays(
    origins: ArrayLike,
    directions: ArrayLike | Sequence[ArrayLike],
    *,
    mirror_normals: ArrayLike | None = None,
    parallel_tol: float = PARALLEL_TOL,
    check_front: bool = True,
    on_degenerate: OnDegenerate = "raise",
) -> RayIntersection:
    """Least-squares intersection of V ≥ 2 rays per point, vectorised over N points.

    Minimises :math:`\\sum_v|(I-\\hat d_v\\hat d_v^T)(\\mathbf X-\\mathbf o_v)|^2` per point. Rays with
    NaN directions are "not seen" and skipped. For two rays this is the midpoint of their common
    perpendicular, evaluated in closed form by eqs (3.5)–(3.7).

    Parameters
    ----------
    origins : (V, 3) or (N, V, 3) array_like, mm
        Ray origins (camera and virtual-camera centres).
    directions : (N, V, 3) array_like, or a sequence of V arrays (N, 3)
        Ray directions (any length; NaN = the view does not see the point).
    mirror_normals : (V, 3) array_like, optional
        Per view, a mirror normal whose reflection :math:`M_v` (3.12) is applied to that view's
        directions first (3.13), or a NaN row for none. Lets a virtual view be given by the
        camera's own mirror rays :math:`\\hat u_2'`.
    parallel_tol : float
        A point whose rays are parallel within this tolerance (:math:`1-k^2` for two rays, the
        smallest eigenvalue of the normalised normal matrix otherwise) is degenerate.
    check_front : bool
        Require the point in front of every origin along its ray (depth > 0).
    on_degenerate : {"raise", "flag"}
        ``"raise"``: :class:`DegenerateGeometry` naming the markers. ``"flag"``: set those
        points to NaN and report them in ``degenerate``.

    Returns
    -------
    RayIntersection

    Raises
    ------
    DegenerateGeometry
        A point seen in fewer than two views, parallel rays, or a point behind a camera.

    Examples
    --------
    >>> import numpy as np
    >>> o = np.array([[0., 0., 0.], [100., 0., 0.]])
    >>> X = np.array([[10., 20., 500.]])
    >>> d = X[:, None, :] - o[None]
    >>> r = intersect_rays(o, d)
    >>> np.allclose(r.points, X), float(r.residual[0]) < 1e-9
    (True, True)
    """
    if on_degenerate not in ("raise", "flag"):
        raise ValueError(f"on_degenerate must be 'raise' or 'flag', got {on_degenerate!r}")
    if isinstance(directions, (list, tuple)):
        views = [_rays(v, f"directions[{i}]") for i, v in enumerate(directions)]
        if len({v.shape for v in views}) != 1:
            raise ValueError("all direction arrays must have the same shape (N, 3)")
    else:
        d = np.asarray(directions, dtype=np.float64)
        if d.ndim != 3 or d.shape[2] != 3:
            raise ValueError(f"directions must have shape (N, V, 3), got {d.shape}")
        views = [d[:, v] for v in range(d.shape[1])]
    n_v, n_pts = len(views), views[0].shape[0]
    o = np.asarray(origins, dtype=np.float64)
    if o.shape not in ((n_v, 3), (n_pts, n_v, 3)):
        raise ValueError(f"origins must have shape ({n_v}, 3) or ({n_pts}, {n_v}, 3), got {o.shape}")
    normals = None
    if mirror_normals is not None:
        normals = np.asarray(mirror_normals, dtype=np.float64).reshape(n_v, 3)
        finite = np.isfinite(normals).all(axis=1)
        normals = np.where(finite[:, None], normals / np.linalg.norm(np.where(finite[:, None], normals, 1.0),
                                                                      axis=1, keepdims=True), np.nan)

    if n_v == 2:
        d1 = views[0]
        if normals is not None and np.isfinite(normals[0]).all():
            d1 = d1 - 2.0 * (d1 @ normals[0])[:, None] * normals[0]
        n2 = normals[1] if normals is not None and np.isfinite(normals[1]).all() else None
        with np.errstate(divide="ignore", invalid="ignore"):  # parallel rays are rejected below
            X, gap, depths, sin2, cos = _two_rays(o[..., 0, :], o[..., 1, :], d1, views[1], n2)
        residual = 0.5 * gap
        few = np.isnan(sin2)  # a NaN direction reaches every term
        n_views = np.where(few, (np.isfinite(views[0]).all(1)).astype(np.intp)
                           + np.isfinite(views[1]).all(1), 2) if few.any() else np.full(n_pts, 2)
        _reject(few, "seen in fewer than two views; check the digitised images", on_degenerate)
        parallel = sin2 < parallel_tol
        _reject(parallel, _PARALLEL_MSG.format(tol=parallel_tol), on_degenerate)
        bad = few | parallel
        if check_front:
            behind = ((depths[:, 0] <= 0.0) | (depths[:, 1] <= 0.0)) & ~bad
            _reject(behind, _BEHIND_MSG, on_degenerate)
            bad |= behind
    else:
        d = np.stack(views, axis=1)
        if normals is not None:
            nz = np.where(np.isfinite(normals), normals, 0.0)
            d = d - 2.0 * np.einsum("nvi,vi->nv", d, nz)[..., None] * nz
        seen = np.isfinite(d).all(axis=2)
        dz = np.where(seen[..., None], d, 0.0)
        length = np.sqrt(_dot(dz, dz))
        dz = dz / np.where(length > 0, length, 1.0)[..., None]
        seen &= length > 0
        n_views = seen.sum(axis=1)
        few = n_views < 2
        _reject(few, "seen in fewer than two views; check the digitised images", on_degenerate)
        oz = np.where(seen[..., None], np.broadcast_to(o, d.shape), 0.0)
        # Normal equations: (n I - sum d d^T) X = sum (o - (o.d) d)
        A = -np.einsum("nvi,nvj->nij", dz, dz)
        A[:, [0, 1, 2], [0, 1, 2]] += n_views[:, None]
        b = (oz - _dot(oz, dz)[..., None] * dz).sum(axis=1)
        lam = np.linalg.eigvalsh(A)[:, 0] / np.maximum(n_views, 1)
        parallel = (lam < 0.5 * parallel_tol) & ~few
        _reject(parallel, _PARALLEL_MSG.format(tol=parallel_tol), on_degenerate)
        ok = ~(few | parallel)
        A[~ok] = np.eye(3)
        X = np.linalg.solve(A, b[..., None])[..., 0]
        rel = X[:, None, :] - np.broadcast_to(o, d.shape)
        depths = np.where(seen, _dot(rel, dz), np.nan)
        perp = rel - np.nan_to_num(depths)[..., None] * dz
        dist2 = np.where(seen, _dot(perp, perp), 0.0)
        residual = np.sqrt(dist2.sum(axis=1) / np.maximum(n_views, 1))
        cosines = np.abs(np.einsum("nvi,nwi->nvw", dz, dz))
        cosines = np.where(seen[:, :, None] & seen[:, None, :], cosines, 1.0)
        cos = cosines.min(axis=(1, 2))
        bad = few | parallel
        if check_front:
            behind = (np.where(seen, depths, np.inf).min(axis=1) <= 0.0) & ~bad
            _reject(behind, _BEHIND_MSG, on_degenerate)
            bad = bad | behind
    if bad.any():
        X = np.where(bad[:, None], np.nan, X)
        residual = np.where(bad, np.nan, residual)
    return RayIntersection(points=X, residual=residual, depths=depths, n_views=n_views, cos_angle=cos,
                           degenerate=bad)


# --------------------------------------------------------------------------- mirror triangulation


@dataclass(frozen=True)
class MirrorTriangulation:
    """Result of :func:`triangulate_mirror` (spec §6.3).

    Attributes
    ----------
    points : (N, 3) mm, reconstructed markers :math:`\\mathbf V`.
    gap : (N,) mm, miss distance :math:`|\\mathbf V_1-\\mathbf V_2|` between the real ray and the
        reflected virtual ray (from the input rays; 0 for exact data): a per-point quality figure.
    a1, a2 : (N,) mm, distances from :math:`\\mathbf F_1` / :math:`\\mathbf F_2` along the rays to the
        closest approach (3.5)–(3.6).
    cos_angle : (N,) :math:`|k|=|\\hat u_1\\cdot\\hat u_2|`; ``angle`` (property) is
        :math:`\\beta=\\arccos|k|` in rad.
    weak : (N,) bool, :math:`\\beta<\\beta_{\\min}` (errors grow like :math:`1/\\sin\\beta`).
    degenerate : (N,) bool, rejected markers (always all False with ``on_degenerate="raise"``).
    virtual_center : (3,) mm, :math:`\\mathbf F_2`.
    reprojection : (N,) px RMS over both images for ``method="optimal"``; ``None`` otherwise.
    method : ``"midpoint"`` or ``"optimal"``.
    """

    points: FloatArray
    gap: FloatArray
    a1: FloatArray
    a2: FloatArray
    cos_angle: FloatArray
    weak: NDArray[np.bool_]
    degenerate: NDArray[np.bool_]
    virtual_center: FloatArray
    reprojection: FloatArray | None
    method: str

    @property
    def angle(self) -> FloatArray:
        """(N,) rad, intersection angle :math:`\\beta=\\arccos|\\hat u_1\\cdot\\hat u_2|` (computed on access)."""
        return np.arccos(np.minimum(self.cos_angle, 1.0))


def triangulate_mirror(
    camera_center: ArrayLike,
    mirror_point: ArrayLike,
    normal: ArrayLike,
    real_rays: ArrayLike | None,
    virtual_rays: ArrayLike | None,
    method: Literal["midpoint", "optimal"] = "midpoint",
    *,
    camera: ProjectingCamera | None = None,
    project: Callable[[FloatArray], FloatArray] | None = None,
    image_xy_real: ArrayLike | None = None,
    image_xy_virtual: ArrayLike | None = None,
    parallel_tol: float = PARALLEL_TOL,
    min_angle: float = MIN_ANGLE,
    max_gap: float | None = None,
    on_degenerate: OnDegenerate = "raise",
) -> MirrorTriangulation:
    """Markers from one camera and one plane mirror (eqs 3.1–3.7, 3.11–3.13).

    ``method="midpoint"`` (the thesis): reflect the mirror ray, :math:`\\hat u_2=M\\hat u_2'`, and
    take the midpoint of the common perpendicular of :math:`\\mathbf F_1+a_1\\hat u_1` and
    :math:`\\mathbf F_2+a_2\\hat u_2` (3.5)–(3.7). ``method="optimal"`` starts there and moves each
    marker to minimise its squared reprojection error in the real and the mirror image
    (``project(X)`` and ``project(reflect(X))``) with :func:`scipy.optimize.least_squares`
    (block-sparse Jacobian; maximum likelihood under isotropic Gaussian pixel noise).

    Parameters
    ----------
    camera_center : (3,) array_like, mm — :math:`\\mathbf F_1`.
    mirror_point : (3,) array_like, mm — :math:`\\mathbf G`.
    normal : (3,) array_like — mirror normal toward the camera (3.10).
    real_rays : (N, 3) array_like or None
        :math:`\\hat u_1`, camera centre → marker (any length). ``None``: ``camera.rays(image_xy_real)``.
    virtual_rays : (N, 3) array_like or None
        :math:`\\hat u_2'`, camera centre → mirror image of the marker. ``None``: from the camera.
    method : {"midpoint", "optimal"}
    camera : object with ``project(points)->(N,2)`` and ``rays(xy)->(N,3)``, optional
        Needed by ``"optimal"`` unless ``project`` is given.
    project : callable, optional
        World points (N, 3) mm → pixels (N, 2); overrides ``camera.project``.
    image_xy_real, image_xy_virtual : (N, 2) array_like, px, optional
        Measured image points; for ``"optimal"`` they default to the projections of the rays.
    parallel_tol, min_angle : float
        Rejection threshold on :math:`1-k^2`; weak-geometry flag threshold (rad, default 2°).
    max_gap : float, optional, mm
        Reject markers whose miss distance exceeds this (no thesis value; off by default).
    on_degenerate : {"raise", "flag"}

    Returns
    -------
    MirrorTriangulation
        ``.points`` (N, 3) mm and ``.gap`` (N,) mm, plus ``a1, a2, angle, weak``.

    Raises
    ------
    DegenerateGeometry
        Parallel rays, a marker behind the camera or virtual camera, a marker not seen, or a
        normal violating (3.10); the message names the marker indices and what to check.

    Examples
    --------
    >>> import numpy as np
    >>> F1, G, n = np.array([0., 0., 1000.]), np.array([-400., 0., 0.]), np.array([1., 0., 0.])
    >>> V = np.array([[100., 50., 300.], [-150., -100., 200.]])
    >>> u1 = V - F1
    >>> u2p = reflect(V, G, n) - F1
    >>> r = triangulate_mirror(F1, G, n, u1, u2p)
    >>> np.allclose(r.points, V), bool(r.gap.max() < 1e-9)
    (True, True)
    """
    F1 = _vec3(camera_center, "camera_center")
    vc = virtual_camera(F1, mirror_point, normal)
    G = _vec3(mirror_point, "mirror_point")
    n = _unit_normal(normal)
    if method not in ("midpoint", "optimal"):
        raise ValueError(f"method must be 'midpoint' or 'optimal', got {method!r}")
    if real_rays is None or virtual_rays is None:
        if camera is None or image_xy_real is None or image_xy_virtual is None:
            raise ValueError("give real_rays and virtual_rays, or a camera with image_xy_real and image_xy_virtual")
        real_rays = camera.rays(np.asarray(image_xy_real, dtype=np.float64))
        virtual_rays = camera.rays(np.asarray(image_xy_virtual, dtype=np.float64))
    u1 = _rays(real_rays, "real_rays")
    u2p = _rays(virtual_rays, "virtual_rays")
    if u1.shape != u2p.shape:
        raise ValueError(f"real_rays {u1.shape} and virtual_rays {u2p.shape} must have the same shape")
    # (3.13) u2 = M u2' is applied inside intersect_rays (mirror_normals), without renormalising
    hit = intersect_rays(np.stack([F1, vc.center]), [u1, u2p], mirror_normals=[[np.nan] * 3, n],
                         parallel_tol=parallel_tol, on_degenerate=on_degenerate)
    gap = 2.0 * hit.residual
    points = hit.points
    degenerate = hit.degenerate
    if max_gap is not None:
        far = gap > max_gap
        _reject(far, f"real and reflected mirror rays miss each other by more than max_gap = {max_gap:g} mm: "
                "check the correspondence, the mirror normal and mirror point", on_degenerate)
        if far.any():
            degenerate = degenerate | far
            points = np.where(far[:, None], np.nan, points)
    reprojection = None
    if method == "optimal":
        proj = project if project is not None else (camera.project if camera is not None else None)
        if proj is None:
            raise ValueError("method='optimal' needs a camera (with .project) or a project callable")
        xy1 = (np.asarray(image_xy_real, dtype=np.float64) if image_xy_real is not None
               else proj(F1 + _unit(u1) * 1000.0))
        xy2 = (np.asarray(image_xy_virtual, dtype=np.float64) if image_xy_virtual is not None
               else proj(F1 + _unit(u2p) * 1000.0))
        ok = ~degenerate
        refined, rep = _refine_reprojection(points[ok], xy1[ok], xy2[ok], G, n, proj)
        points = points.copy()
        points[ok] = refined
        reprojection = np.full(points.shape[0], np.nan)
        reprojection[ok] = rep
    return MirrorTriangulation(
        points=points, gap=gap, a1=hit.depths[:, 0], a2=hit.depths[:, 1], cos_angle=hit.cos_angle,
        weak=hit.cos_angle > np.cos(min_angle), degenerate=degenerate, virtual_center=vc.center,
        reprojection=reprojection, method=method,
    )


def _refine_reprojection(
    X0: FloatArray,
    xy1: FloatArray,
    xy2: FloatArray,
    G: FloatArray,
    n: FloatArray,
    proj: Callable[[FloatArray], FloatArray],
) -> tuple[FloatArray, FloatArray]:
    """Per-marker minimisation of the real + mirror reprojection error (all markers in one call)."""
    m = X0.shape[0]
    if m == 0:
        return X0, np.zeros(0)

    def residuals(x: FloatArray) -> FloatArray:
        X = x.reshape(m, 3)
        r1 = proj(X) - xy1
        r2 = proj(reflect(X, G, n)) - xy2
        return np.concatenate([r1, r2], axis=1).ravel()  # marker-major: 4 residuals per marker

    # Block-diagonal sparsity: residuals 4i..4i+3 depend on parameters 3i..3i+2 only.
    rows = np.repeat(np.arange(4 * m), 3)
    cols = (np.arange(m)[:, None, None] * 3 + np.arange(3)[None, None, :]).repeat(4, axis=1).ravel()
    sparsity = scipy.sparse.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(4 * m, 3 * m))
    sol = least_squares(residuals, X0.ravel(), jac_sparsity=sparsity, method="trf", tr_solver="lsmr",
                        x_scale="jac", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=50)
    X = sol.x.reshape(m, 3)
    rep = np.sqrt((sol.fun.reshape(m, 4) ** 2).sum(axis=1) / 2.0)
    return X, rep


def triangulate_mirrors(
    camera_center: ArrayLike,
    mirrors: Sequence[tuple[ArrayLike, ArrayLike]],
    real_rays: ArrayLike,
    virtual_rays: ArrayLike,
    *,
    parallel_tol: float = PARALLEL_TOL,
    on_degenerate: OnDegenerate = "raise",
) -> RayIntersection:
    """Markers from one camera and several plane mirrors (one virtual camera per mirror).

    Every view that sees a marker is used: the real ray and, for each mirror j, the reflected
    mirror ray from the virtual camera :math:`\\mathbf F_{2,j}`, intersected by :func:`intersect_rays`.

    Parameters
    ----------
    camera_center : (3,) array_like, mm.
    mirrors : sequence of ``(mirror_point, normal)``, J mirrors (normals toward the camera).
    real_rays : (N, 3) array_like — direct rays; NaN rows = marker not seen directly.
    virtual_rays : (N, J, 3) array_like — camera → mirror image in mirror j; NaN = not seen.
    parallel_tol, on_degenerate : see :func:`intersect_rays`.

    Returns
    -------
    RayIntersection
        ``depths[:, 0]`` is along the real ray, ``depths[:, 1 + j]`` along the virtual ray of mirror j.

    Examples
    --------
    >>> import numpy as np
    >>> F1 = np.array([0., 0., 1000.])
    >>> mirrors = [([-400., 0., 0.], [1., 0., 0.]), ([0., -400., 0.], [0., 1., 0.])]
    >>> V = np.array([[100., 50., 300.]])
    >>> virt = np.stack([reflect(V, G, n) - F1 for G, n in mirrors], axis=1)
    >>> virt[0, 1] = np.nan                      # not seen in the second mirror
    >>> np.allclose(triangulate_mirrors(F1, mirrors, V - F1, virt).points, V)
    True
    """
    F1 = _vec3(camera_center, "camera_center")
    u1 = _rays(real_rays, "real_rays")
    u2p = np.asarray(virtual_rays, dtype=np.float64)
    if u2p.ndim == 2:
        u2p = u2p[:, None, :]
    if u2p.ndim != 3 or u2p.shape[0] != u1.shape[0] or u2p.shape[1] != len(mirrors) or u2p.shape[2] != 3:
        raise ValueError(f"virtual_rays must have shape ({u1.shape[0]}, {len(mirrors)}, 3), got {u2p.shape}")
    normals = np.stack([_unit_normal(nm) for _, nm in mirrors])
    centers = np.stack([virtual_camera(F1, G, nm).center for G, nm in mirrors])
    return intersect_rays(np.concatenate([F1[None], centers]), [u1, *np.moveaxis(u2p, 1, 0)],
                          mirror_normals=np.concatenate([np.full((1, 3), np.nan), normals]),
                          parallel_tol=parallel_tol, on_degenerate=on_degenerate)
