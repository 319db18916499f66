"""Camera, finite plane mirrors and the calibration grid of the virtual lab.

The lab's optics are its own (a pinhole with OpenCV's distortion model, reflection in a plane),
written out here rather than taken from the photogrammetry plugin: the truth computed with them
validates that plugin, so a bug shared by both would cancel out (``tests/instruments/virtual_lab`` cross-checks
the two).

* :func:`look_at_camera` builds a :class:`LabCamera` (pinhole projection with OpenCV's radial and
  tangential distortion) from a position, a target, a focal length and a sensor size, in mm. The
  camera axes follow OpenCV: x right, y down, z along the optical axis.
* :class:`Mirror` is a finite rectangular plane mirror. A marker is seen in it only when the ray
  from the camera to the marker's virtual image (its reflection) crosses the rectangle.
* :func:`view_points` gives the image position and visibility of points seen directly and in each
  mirror (virtual image = projection of the reflected point through the real camera).
* :func:`calibration_grid` / :func:`thesis_grid_points`: the planar calibration grid on Z = 0.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["LabCamera", "Mirror", "Views", "calibration_grid", "camera_frame", "look_at_camera", "thesis_grid_points",
           "view_points", "THESIS_GRID_X", "THESIS_GRID_Y"]

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

#: Calibration-grid X and Y values of the thesis program (``photogrammetry.md`` §10, DATA 2900), mm.
THESIS_GRID_X = (-849.0, -728.5, -607.5, -485.0, -364.0, -241.5, -120.5, 0.0, 121.0, 243.0, 365.0, 486.0, 607.0)
THESIS_GRID_Y = (-486.0, -365.0, -244.0, -122.0, 0.0, 121.0, 243.0)


def _unit(v: ArrayLike) -> FloatArray:
    v = np.asarray(v, dtype=float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


#: Distortion coefficients the lab's camera models: OpenCV's ``(k1, k2, p1, p2, k3)``.
DISTORTION_TERMS = 5


@dataclass(frozen=True)
class LabCamera:
    """A pinhole camera with OpenCV's lens distortion (``k1, k2, p1, p2, k3``), mm and px.

    The same model and conventions as OpenCV's ``projectPoints`` (and the photogrammetry plugin's
    ``PinholeCamera``): ``x = R X + t``, normalised ``(x/z, y/z)``, radial factor
    ``1 + k1 r² + k2 r⁴ + k3 r⁶`` and tangential terms, then ``u = fx x'' + cx``, ``v = fy y'' + cy``
    (no skew), pixel centres at integer coordinates.

    Attributes
    ----------
    K : (3, 3) intrinsic matrix, px.
    dist : (5,) distortion coefficients ``(k1, k2, p1, p2, k3)`` (fewer are padded with zeros).
    R : (3, 3) world -> camera rotation.
    t : (3,) world -> camera translation, mm.
    image_size : (width, height) px, or ``None``.

    Examples
    --------
    >>> cam = LabCamera(np.array([[1000., 0, 320], [0, 1000., 240], [0, 0, 1]]), np.zeros(5), np.eye(3), np.zeros(3))
    >>> cam.project([[0.0, 0.0, 1000.0], [100.0, 0.0, 1000.0]]).tolist()
    [[320.0, 240.0], [420.0, 240.0]]
    """

    K: FloatArray
    dist: FloatArray
    R: FloatArray
    t: FloatArray
    image_size: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        dist = np.asarray(self.dist, dtype=float).ravel()
        if dist.size > DISTORTION_TERMS:
            raise ValueError(f"the virtual lab's camera models {DISTORTION_TERMS} distortion coefficients "
                             f"(k1, k2, p1, p2, k3), got {dist.size}")
        object.__setattr__(self, "K", np.asarray(self.K, dtype=float).reshape(3, 3))
        object.__setattr__(self, "dist", np.pad(dist, (0, DISTORTION_TERMS - dist.size)))
        object.__setattr__(self, "R", np.asarray(self.R, dtype=float).reshape(3, 3))
        object.__setattr__(self, "t", np.asarray(self.t, dtype=float).reshape(3))

    @property
    def camera_center(self) -> FloatArray:
        """Projection centre ``-Rᵀ t`` in world coordinates, mm."""
        return -self.R.T @ self.t

    def project(self, points: ArrayLike) -> FloatArray:
        """Pixel coordinates (N, 2) of world points (N, 3), mm (NaN for a point in the camera's plane z = 0)."""
        P = np.asarray(points, dtype=float).reshape(-1, 3)
        Pc = P @ self.R.T + self.t
        with np.errstate(divide="ignore", invalid="ignore"):
            x, y = Pc[:, 0] / Pc[:, 2], Pc[:, 1] / Pc[:, 2]
        k1, k2, p1, p2, k3 = self.dist
        r2 = x * x + y * y
        radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3))
        xd = x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x)
        yd = y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y
        return np.stack([self.K[0, 0] * xd + self.K[0, 2], self.K[1, 1] * yd + self.K[1, 2]], axis=-1)


def look_at_camera(position: ArrayLike, target: ArrayLike, focal_mm: float,
                   sensor_mm: tuple[float, float] = (36.0, 24.0), image_size: tuple[int, int] = (1800, 1200),
                   up: ArrayLike = (0.0, 1.0, 0.0), roll: float = 0.0,
                   distortion: Sequence[float] = (0.0, 0.0, 0.0, 0.0, 0.0),
                   principal_offset_px: tuple[float, float] = (0.0, 0.0)) -> LabCamera:
    """A pinhole camera at ``position`` looking at ``target`` (any tilt), mm.

    Parameters
    ----------
    position, target : (3,) array_like, mm
        Projection centre and a point on the optical axis.
    focal_mm : float
        Focal length (image distance), mm.
    sensor_mm : (width, height), mm
        Imaged area of the sensor or film (35 mm still: 36 x 24; cine: 24 x 18).
    image_size : (width, height), px
        Pixels across the sensor; pixel centres at integer coordinates (OpenCV).
    up : (3,) array_like
        World direction that appears upward in the image (must not be parallel to the axis).
    roll : float
        Extra rotation about the optical axis, rad (positive turns the image clockwise).
    distortion : sequence
        OpenCV coefficients ``(k1, k2, p1, p2, k3)`` on normalised coordinates (radial: k1, k2, k3).
    principal_offset_px : (dx, dy)
        Principal point offset from the image centre, px.

    Returns
    -------
    LabCamera

    Examples
    --------
    >>> cam = look_at_camera([0, 0, 1000], [0, 0, 0], 30.0, (36.0, 24.0), (1800, 1200))
    >>> cam.project([[0.0, 0.0, 0.0], [100.0, 0.0, 0.0]]).round(6).tolist()
    [[899.5, 599.5], [1049.5, 599.5]]
    """
    C = np.asarray(position, dtype=float).reshape(3)
    R = camera_frame(C, target, up, roll)
    w, h = (int(s) for s in image_size)
    fx = focal_mm * w / sensor_mm[0]
    fy = focal_mm * h / sensor_mm[1]
    K = np.array([[fx, 0.0, (w - 1) / 2 + principal_offset_px[0]],
                  [0.0, fy, (h - 1) / 2 + principal_offset_px[1]],
                  [0.0, 0.0, 1.0]])
    return LabCamera(K, np.asarray(distortion, dtype=float), R, -R @ C, (w, h))


def camera_frame(position: ArrayLike, target: ArrayLike, up: ArrayLike = (0.0, 1.0, 0.0),
                 roll: float = 0.0) -> FloatArray:
    """World -> camera rotation (rows: camera x right, y down, z forward), det +1."""
    z = _unit(np.asarray(target, float) - np.asarray(position, float))
    u = np.asarray(up, dtype=float)
    y = -(u - (u @ z) * z)
    if np.linalg.norm(y) < 1e-9 * max(np.linalg.norm(u), 1e-300):
        raise ValueError("the `up` direction is parallel to the optical axis; give another `up`")
    y = _unit(y)
    x = np.cross(y, z)
    c, s = np.cos(roll), np.sin(roll)
    x, y = c * x + s * y, -s * x + c * y
    return np.stack([x, y, z])


@dataclass(frozen=True)
class Mirror:
    """A finite rectangular plane mirror (the silvered face).

    Attributes
    ----------
    centre : (3,) mm, the rectangle's centre (a point G on the reflecting surface).
    normal : (3,) unit normal on the reflecting side (toward the camera).
    width, height : mm, along :attr:`axes` ``u`` (width) and ``v`` (height).
    up : (3,) direction the height runs along (projected into the plane; default world Y).

    Examples
    --------
    >>> m = Mirror([0.0, 0.0, 0.0], [0.0, 0.0, 1.0], 100.0, 100.0)
    >>> m.crosses([[0, 0, 50], [0, 0, 50]], [[10, 0, -50], [150, 0, -50]]).tolist()
    [True, False]
    """

    centre: FloatArray
    normal: FloatArray
    width: float
    height: float
    up: FloatArray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))

    def __post_init__(self) -> None:
        object.__setattr__(self, "centre", np.asarray(self.centre, dtype=float).reshape(3))
        object.__setattr__(self, "normal", _unit(np.asarray(self.normal, dtype=float).reshape(3)))
        object.__setattr__(self, "up", np.asarray(self.up, dtype=float).reshape(3))
        if self.width <= 0 or self.height <= 0:
            raise ValueError(f"mirror width and height must be > 0 mm (got {self.width}, {self.height})")

    @property
    def axes(self) -> tuple[FloatArray, FloatArray]:
        """In-plane unit vectors ``(u, v)``: ``v`` along ``up`` projected into the plane, ``u = v x n``."""
        n = self.normal
        v = self.up - (self.up @ n) * n
        if np.linalg.norm(v) < 1e-9:
            v = np.cross(n, [1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.cross(n, [0.0, 0.0, 1.0])
        v = _unit(v)
        return _unit(np.cross(v, n)), v

    def corners(self) -> FloatArray:
        """The four corners (4, 3), mm, in order around the rectangle."""
        u, v = self.axes
        s = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float)
        return self.centre + 0.5 * (s[:, :1] * self.width * u + s[:, 1:] * self.height * v)

    def reflect(self, points: ArrayLike) -> FloatArray:
        """Mirror images ``(..., 3)`` of points (the virtual markers): ``x - 2 ((x - G) . n) n``, mm."""
        x = np.asarray(points, dtype=float)
        return x - 2.0 * ((x - self.centre) @ self.normal)[..., None] * self.normal

    def virtual_centre(self, camera_centre: ArrayLike) -> FloatArray:
        """The camera's mirror image ``F2`` (``photogrammetry.md`` §7): its centre reflected, mm.

        Raises
        ------
        ValueError
            The camera is not in front of the mirror's reflecting side.
        """
        C = np.asarray(camera_centre, dtype=float).reshape(3)
        if not self.side(C) > 0:
            raise ValueError(f"the camera at {C.round(3).tolist()} mm is not in front of the mirror at "
                             f"{self.centre.round(3).tolist()} mm (normal {self.normal.round(6).tolist()}): "
                             "turn the normal toward the camera")
        return self.reflect(C)

    def side(self, points: ArrayLike) -> FloatArray:
        """Signed distance ``(points - G) . n`` (mm); > 0 on the reflecting side."""
        return (np.asarray(points, dtype=float) - self.centre) @ self.normal

    def crosses(self, origins: ArrayLike, targets: ArrayLike) -> BoolArray:
        """Whether each segment ``origin -> target`` passes through the mirror rectangle."""
        o = np.asarray(origins, dtype=float)
        q = np.asarray(targets, dtype=float)
        so, sq = self.side(o), self.side(q)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = so / (so - sq)
        hit = (so * sq < 0) & np.isfinite(s)
        x = o + np.where(hit, s, 0.0)[..., None] * (q - o) - self.centre
        u, v = self.axes
        return hit & (np.abs(x @ u) <= 0.5 * self.width) & (np.abs(x @ v) <= 0.5 * self.height)


@dataclass(frozen=True)
class Views:
    """Image positions of points seen directly and in each mirror.

    Attributes
    ----------
    real_xy : (T, M, 2) px, NaN where not visible.
    real_visible : (T, M) bool.
    virtual_xy : (T, K, M, 2) px of the mirror images in mirror k, NaN where not visible.
    virtual_visible : (T, K, M) bool.
    virtual_points : (T, K, M, 3) mm, the reflected (virtual) points.
    """

    real_xy: FloatArray
    real_visible: BoolArray
    virtual_xy: FloatArray
    virtual_visible: BoolArray
    virtual_points: FloatArray


def _in_view(camera: LabCamera, points: FloatArray) -> tuple[FloatArray, BoolArray]:
    """Pixel positions (..., 2) and 'in front and inside the frame' (...,) of points (..., 3)."""
    shape = points.shape[:-1]
    P = points.reshape(-1, 3)
    Pc = P @ np.asarray(camera.R, float).T + np.asarray(camera.t, float).reshape(3)
    xy = camera.project(P)
    w, h = camera.image_size if camera.image_size is not None else (np.inf, np.inf)
    # the distortion polynomial folds back far outside the field: also bound the ideal coordinates
    K = np.asarray(camera.K, float)
    corners_n = np.abs((np.array([[0.0, 0.0], [w - 1.0, h - 1.0]]) - K[:2, 2]) / np.diag(K)[:2]).max(axis=0)
    with np.errstate(divide="ignore", invalid="ignore"):
        n = Pc[:, :2] / Pc[:, 2:3]
    ok = ((Pc[:, 2] > 0) & np.all(np.abs(n) <= 1.5 * corners_n, axis=1)
          & (xy[:, 0] >= 0) & (xy[:, 0] <= w - 1) & (xy[:, 1] >= 0) & (xy[:, 1] <= h - 1))
    return xy.reshape(*shape, 2), ok.reshape(shape)


def facing(normals: FloatArray, points: FloatArray, viewpoint: ArrayLike) -> BoolArray:
    """Flat markers whose face looks at ``viewpoint``; spherical markers (NaN normal) always do."""
    d = np.einsum("...i,...i->...", np.asarray(viewpoint, float) - points, normals)
    return np.isnan(d) | (d > 0)


def view_points(camera: LabCamera, mirrors: Sequence[Mirror], points: ArrayLike,
                normals: ArrayLike | None = None, hidden_real: ArrayLike | None = None,
                hidden_virtual: ArrayLike | None = None) -> Views:
    """Where points appear in the image, directly and in each finite mirror.

    A point is seen directly when it is in front of the camera, inside the frame, faces the camera
    (flat markers) and no mirror's back blocks the line of sight. It is seen in mirror ``k`` when it
    lies on the reflecting side, faces the virtual camera, the ray from the camera to its reflection
    crosses the mirror rectangle, and the reflection projects inside the frame.

    Parameters
    ----------
    camera : LabCamera
    mirrors : sequence of Mirror
    points : (T, M, 3) mm
    normals : (T, M, 3), optional
        Marker normals (NaN rows: spheres).
    hidden_real, hidden_virtual : (T, M) and (T, K, M) bool, optional
        Self-occlusion of the scene seen from the camera and from each virtual camera.

    Returns
    -------
    Views
    """
    P = np.asarray(points, dtype=float)
    T, M = P.shape[:2]
    N = np.full_like(P, np.nan) if normals is None else np.asarray(normals, dtype=float)
    C = camera.camera_center
    xy, vis = _in_view(camera, P)
    vis &= facing(N, P, C) & np.all(np.isfinite(P), axis=-1)
    for m in mirrors:
        vis &= ~m.crosses(np.broadcast_to(C, P.shape), P)
    if hidden_real is not None:
        vis &= ~np.asarray(hidden_real, bool)
    K = len(mirrors)
    vxy = np.full((T, K, M, 2), np.nan)
    vvis = np.zeros((T, K, M), dtype=bool)
    vpts = np.full((T, K, M, 3), np.nan)
    for k, m in enumerate(mirrors):
        V = m.reflect(P)
        F2 = m.virtual_centre(C)
        pxy, ok = _in_view(camera, V)
        ok &= (m.side(P) > 0) & facing(N, P, F2) & m.crosses(np.broadcast_to(C, V.shape), V)
        for j, other in enumerate(mirrors):       # another mirror's back in the way of the reflected ray
            if j != k:
                ok &= ~other.crosses(np.broadcast_to(C, V.shape), V)
        if hidden_virtual is not None:
            ok &= ~np.asarray(hidden_virtual, bool)[:, k]
        vxy[:, k] = np.where(ok[..., None], pxy, np.nan)
        vvis[:, k] = ok
        vpts[:, k] = V
    return Views(np.where(vis[..., None], xy, np.nan), vis, vxy, vvis, vpts)


def calibration_grid(pitch: float = 60.0, shape: tuple[int, int] = (25, 17),
                     origin: tuple[float, float] = (0.0, 0.0), z: float = 0.0) -> FloatArray:
    """Nodes (nx * ny, 3) of a planar grid of ``pitch`` mm on Z = ``z``, centred on ``origin``.

    Order: X outer, Y inner (like the thesis numbering). The thesis used a 60 mm pitch on Z = 0.

    Examples
    --------
    >>> calibration_grid(60.0, (3, 2)).tolist()[:3]
    [[-60.0, -30.0, 0.0], [-60.0, 30.0, 0.0], [0.0, -30.0, 0.0]]
    """
    nx, ny = shape
    if nx < 1 or ny < 1 or pitch <= 0:
        raise ValueError(f"grid needs shape >= (1, 1) and pitch > 0 (got {shape}, {pitch})")
    x = (np.arange(nx) - (nx - 1) / 2) * pitch + origin[0]
    y = (np.arange(ny) - (ny - 1) / 2) * pitch + origin[1]
    X, Y = np.meshgrid(x, y, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), np.full(X.size, float(z))], -1)


def thesis_grid_points() -> FloatArray:
    """The 91 calibration points of the thesis program (DATA 2900), numbered ``7I + II + 53``.

    Examples
    --------
    >>> p = thesis_grid_points()
    >>> p.shape, p[0].tolist(), p[53].tolist()
    ((91, 3), [-849.0, -486.0, 0.0], [0.0, 0.0, 0.0])
    """
    X, Y = np.meshgrid(THESIS_GRID_X, THESIS_GRID_Y, indexing="ij")
    return np.stack([X.ravel(), Y.ravel(), np.zeros(X.size)], -1)
