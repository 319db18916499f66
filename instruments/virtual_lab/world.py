"""The tracking world: moving spheres, the mirror centre, the camera and the lamp.

One :class:`TrackingWorld` is the ground-truth scene of the direction trackers and the active
mirror (``instruments.md`` §2–§4). A simulator takes it as its ``world`` constructor argument, so
one object handed to several simulators makes them see the same scene. World frame: right-handed,
mm, ``y`` up; the mirror centre ``O`` at the origin by default and the camera 6 m away along ``+z``.

Axis angles (:func:`axis_angles`) are those of the gimbal's Cardan mount: ``h`` about ``+y`` from the
camera direction, ``v`` the elevation above the camera direction's elevation, both rad.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Path:
    """A point that stands still until ``start_s``, then moves on a line or a circle.

    Parameters
    ----------
    origin
        Position at rest (line) or centre of the circle, mm.
    velocity
        Line velocity, mm/s (ignored for a circle).
    radius
        Circle radius, mm; 0 = a line.
    rate
        Circle angular rate about ``+y``, rad/s.
    phase
        Angle of the point on the circle at ``start_s``, rad about ``+y`` from ``+z``.
    start_s
        Time the motion starts, s.
    vertical
        The circle lies in the vertical ``x``-``y`` plane (a turntable facing ``+z``), its angle
        measured from ``+y`` toward ``+x``; otherwise it is horizontal, about ``+y``.

    Examples
    --------
    >>> p = Path((0.0, 0.0, 0.0), radius=1000.0, rate=math.pi / 2)
    >>> np.round(p.position(1.0), 6).tolist()
    [1000.0, 0.0, 0.0]
    >>> (np.round(Path((0.0, 0.0, 1000.0), radius=160.0, rate=1.0, vertical=True).position(0.0), 6) + 0.0).tolist()
    [0.0, 160.0, 1000.0]
    """

    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    rate: float = 0.0
    phase: float = 0.0
    start_s: float = 0.0
    vertical: bool = False

    def position(self, t: float) -> FloatArray:
        """Position at time ``t`` (s), mm ``(3,)``."""
        dt = max(0.0, t - self.start_s)
        o = np.asarray(self.origin, dtype=float)
        if self.radius == 0.0:
            return o + dt * np.asarray(self.velocity, dtype=float)
        a = self.phase + self.rate * dt
        if self.vertical:
            return o + self.radius * np.array([math.sin(a), math.cos(a), 0.0])
        return o + self.radius * np.array([math.sin(a), 0.0, math.cos(a)])


@dataclass(frozen=True)
class Sphere:
    """A diffusely reflecting sphere on a :class:`Path`: ``radius`` mm, ``brightness`` (white = 1)."""

    path: Path
    radius: float = 125.0
    brightness: float = 1.0


@dataclass(frozen=True)
class TrackingWorld:
    """The scene every tracker simulator of a session sees.

    Parameters
    ----------
    spheres
        The targets (the first is *the* target whose truth is reported).
    mirror_centre
        Mirror point ``O``, mm.
    camera
        Camera centre, mm.
    lamp
        Lamp position (lights the spheres, intensity ~ 1 / distance^2), mm.
    mirror_size
        Side of the square mirror, mm.

    Examples
    --------
    >>> w = TrackingWorld((Sphere(Path((3000.0, 0.0, 3000.0))),))
    >>> [round(math.degrees(a), 3) for a in w.target_angles(0.0)]
    [45.0, 0.0]
    """

    spheres: tuple[Sphere, ...] = field(default_factory=lambda: (Sphere(Path((0.0, 0.0, 3000.0))),))
    mirror_centre: tuple[float, float, float] = (0.0, 0.0, 0.0)
    camera: tuple[float, float, float] = (0.0, 0.0, 6000.0)
    lamp: tuple[float, float, float] = (0.0, 500.0, 500.0)
    mirror_size: float = 1000.0

    @property
    def camera_direction(self) -> FloatArray:
        """Unit vector from ``O`` to the camera."""
        c = np.asarray(self.camera, dtype=float) - np.asarray(self.mirror_centre, dtype=float)
        return c / np.linalg.norm(c)

    def target_position(self, t: float) -> FloatArray:
        """Centre of the first sphere at ``t`` (s), mm."""
        return self.spheres[0].path.position(t)

    def target_angles(self, t: float) -> tuple[float, float]:
        """``(h, v)`` axis angles of the target direction seen from ``O`` at ``t`` (s), rad."""
        h, v = axis_angles(self.target_position(t) - np.asarray(self.mirror_centre, dtype=float),
                           self.camera_direction)
        return float(h), float(v)

    def lamp_factor(self, point: ArrayLike, reference: float = 3000.0) -> float:
        """Illumination of ``point`` relative to a lamp at ``reference`` mm: ``(reference / distance)^2``."""
        d = float(np.linalg.norm(np.asarray(point, dtype=float) - np.asarray(self.lamp, dtype=float)))
        return (reference / max(d, 1.0)) ** 2


def axis_angles(direction: ArrayLike, camera_direction: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Cardan axis angles ``(h, v)`` of ``direction`` against ``camera_direction``, rad.

    ``h``: azimuth about ``+y`` (from ``+z`` toward ``+x``) minus the camera's; ``v``: elevation minus
    the camera's. Both broadcast over leading dimensions of ``(..., 3)`` inputs.

    Examples
    --------
    >>> h, v = axis_angles([1.0, 1.0, 1.0], [0.0, 0.0, 1.0])
    >>> round(math.degrees(float(h)), 3), round(math.degrees(float(v)), 3)
    (45.0, 35.264)
    """
    d, c = np.asarray(direction, dtype=float), np.asarray(camera_direction, dtype=float)

    def az_el(u: FloatArray) -> tuple[FloatArray, FloatArray]:
        return np.arctan2(u[..., 0], u[..., 2]), np.arctan2(u[..., 1], np.hypot(u[..., 0], u[..., 2]))

    (ad, ed), (ac, ec) = az_el(d), az_el(c)
    return ad - ac, ed - ec


def mirror_normal(h: float, v: float, camera_direction: ArrayLike) -> FloatArray:
    """Unit mirror normal at Cardan angles ``(h, v)`` (rad); ``(0, 0)`` faces the camera.

    Examples
    --------
    >>> np.round(mirror_normal(math.pi / 8, 0.0, [0.0, 0.0, 1.0]), 6).tolist()
    [0.382683, 0.0, 0.92388]
    """
    c = np.asarray(camera_direction, dtype=float)
    az = math.atan2(c[0], c[2]) + h
    el = math.atan2(c[1], math.hypot(c[0], c[2])) + v
    return np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])


def image_in_mirror(camera: ArrayLike, point: ArrayLike, centre: ArrayLike, normal: ArrayLike,
                    size: float, radius: float = 0.0) -> bool:
    """Whether the camera sees ``point``'s mirror image (a disc of ``radius`` mm) inside the square mirror.

    With the virtual point ``V' = V - 2((V - O) . t) t``, the ray camera -> ``V'`` meets the mirror
    plane at ``X``; the image lies inside when ``X`` (widened by the disc's footprint) is inside the
    ``size`` x ``size`` square about ``O`` (``instruments.md`` §4.4). All lengths mm.

    Examples
    --------
    >>> n = mirror_normal(math.radians(45.0), 0.0, [0.0, 0.0, 1.0])   # bisects camera (+z) and target (+x)
    >>> image_in_mirror([0, 0, 6000], [3000, 0, 0], [0, 0, 0], n, 1000.0, 125.0)
    True
    >>> image_in_mirror([0, 0, 6000], [3000, 0, 1500], [0, 0, 0], n, 1000.0, 125.0)
    False
    """
    C, V, O = (np.asarray(x, dtype=float) for x in (camera, point, centre))
    t = np.asarray(normal, dtype=float)
    if np.dot(V - O, t) <= 0 or np.dot(C - O, t) <= 0:
        return False                      # object or camera behind the mirror
    Vp = V - 2.0 * np.dot(V - O, t) * t
    ray = Vp - C
    s = np.dot(O - C, t) / np.dot(ray, t)
    X = C + s * ray - O
    # In-plane axes: horizontal (perpendicular to t and y) and the one perpendicular to both.
    e1 = np.cross([0.0, 1.0, 0.0], t)
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(t, e1)
    footprint = radius * s                # the disc's image radius on the mirror plane
    half = size / 2.0 - footprint
    return bool(abs(np.dot(X, e1)) <= half and abs(np.dot(X, e2)) <= half)
