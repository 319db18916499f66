"""The tracking world: moving spheres, the mirror centre, the camera and the lamp.

One :class:`TrackingWorld` is the ground-truth scene of the direction trackers and the active
mirror (``instruments.md`` §2–§4). A simulator takes it, or a :class:`SharedWorld` holding it, as
its ``world`` constructor argument: one :class:`SharedWorld` handed to several simulators makes them
see the same scene on one clock (a session's ``[world]``, :mod:`.worlds`). World frame: right-handed,
mm, ``y`` up; the mirror centre ``O`` at the origin by default and the camera 6 m away along ``+z``.

Axis angles (:func:`axis_angles`) are those of the gimbal's Cardan mount: ``h`` about ``+y`` from the
camera direction, ``v`` the elevation above the camera direction's elevation, both rad.
"""

from __future__ import annotations

import bisect
import math
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np
from mirrorlab.core.devices import CommandError, LineSimulator
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
    axes
        An ellipse (or, with one axis zero, a back-and-forth line) instead of a circle: the point is
        ``origin + axes[0] sin(a) + axes[1] cos(a)``, ``a = phase + rate (t - start_s)``, mm.
    end_s
        Time the motion stops (the point stays where it is then), s.

    Examples
    --------
    >>> p = Path((0.0, 0.0, 0.0), radius=1000.0, rate=math.pi / 2)
    >>> np.round(p.position(1.0), 6).tolist()
    [1000.0, 0.0, 0.0]
    >>> (np.round(Path((0.0, 0.0, 1000.0), radius=160.0, rate=1.0, vertical=True).position(0.0), 6) + 0.0).tolist()
    [0.0, 160.0, 1000.0]
    >>> stage = Path((0.0, 0.0, 1000.0), axes=((100.0, 0.0, 0.0), (0.0, 0.0, 0.0)), rate=math.pi)
    >>> np.round(stage.position(0.5), 6).tolist()
    [100.0, 0.0, 1000.0]
    >>> Path(velocity=(1.0, 0.0, 0.0), end_s=2.0).position(5.0).tolist()
    [2.0, 0.0, 0.0]
    """

    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    rate: float = 0.0
    phase: float = 0.0
    start_s: float = 0.0
    vertical: bool = False
    axes: tuple[tuple[float, float, float], tuple[float, float, float]] | None = None
    end_s: float = math.inf

    def position(self, t: float) -> FloatArray:
        """Position at time ``t`` (s), mm ``(3,)``."""
        dt = max(0.0, min(t, self.end_s) - self.start_s)
        o = np.asarray(self.origin, dtype=float)
        if self.axes is not None:
            a = self.phase + self.rate * dt
            return o + math.sin(a) * np.asarray(self.axes[0], dtype=float) \
                + math.cos(a) * np.asarray(self.axes[1], dtype=float)
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


def turntable_world(radius: float = 160.0, period: float = 1.84, range_mm: float = 1000.0,
                    start_s: float = 0.0) -> TrackingWorld:
    """The §3.4 turntable: a 150 mm disc circling ``radius`` mm every ``period`` s, ``range_mm`` ahead of ``+z``.

    The disc turns in the plane facing the detector (at the origin, looking along ``+z``); one lamp
    2 m to the side (``-x``: the low-pixel side of a detector is lit, as in Fig. 4.34). The disc's
    reflectance 0.35 makes a 6.5 kHz exposure peak near 190 counts (a simulator choice).

    Examples
    --------
    >>> w = turntable_world()
    >>> np.round(w.target_position(1.84 / 4), 3).tolist()      # a quarter turn: 160 mm to the side
    [160.0, 0.0, 1000.0]
    """
    path = Path((0.0, 0.0, range_mm), radius=radius, rate=2 * math.pi / period, start_s=start_s, vertical=True)
    return TrackingWorld((Sphere(path, DISC_RADIUS, DISC_BRIGHTNESS),), mirror_centre=(0.0, 0.0, 0.0),
                         camera=(0.0, 0.0, 6000.0), lamp=(-2000.0, 0.0, range_mm))


DISC_RADIUS = 75.0               # the 150 mm turntable disc, mm
DISC_BRIGHTNESS = 0.35


class SharedWorld:
    """A :class:`TrackingWorld` that several simulators see at once, on one clock.

    A simulator given a ``SharedWorld`` reads its scene from :attr:`world` (so a ``SIM:LOAD`` on one
    simulator moves the target for all of them) and, when the world has a ``clock``, runs on it:
    its own clock (``TIME?``, stream stamps) follows :meth:`now`, so every simulator of the world
    agrees on the time (with a session's clock: session seconds). Without a ``clock`` the world is
    private: the simulator keeps its own clock (and ``SIM:CLOCK FAST`` skips command delays).

    The active mirror logs its angles here (:meth:`note_mirror`), so the truth of the world
    (:meth:`truth`) has the mirror normal at any time.

    Parameters
    ----------
    world
        The scene.
    clock
        World time, s (e.g. a session's ``clock.now``); ``None``: a private world.

    Examples
    --------
    >>> shared = SharedWorld(TrackingWorld(), clock=lambda: 2.0)
    >>> shared.catch_up(0.5, clock_ms=1500.0), SharedWorld(TrackingWorld()).catch_up(0.5, clock_ms=1500.0)
    (0.5, 0.5)
    """

    def __init__(self, world: TrackingWorld, clock: Callable[[], float] | None = None) -> None:
        self.clock = clock
        self._lock = threading.Lock()
        self._times: list[float] = [-math.inf]
        self._worlds: list[TrackingWorld] = [world]
        self._mirror: list[tuple[float, float, float]] = []

    @property
    def shared(self) -> bool:
        """Whether the world runs on its own clock (shared), not on each simulator's."""
        return self.clock is not None

    def now(self) -> float:
        """World time, s (0 for a private world)."""
        return self.clock() if self.clock is not None else 0.0

    def catch_up(self, seconds: float, clock_ms: float) -> float:
        """How far (s) a simulator whose clock reads ``clock_ms`` advances when its server asks for ``seconds``.

        Private world: ``seconds``. Shared world: up to the world's time, never back.
        """
        if self.clock is None:
            return seconds
        return max(0.0, self.clock() - clock_ms / 1000.0)

    @property
    def world(self) -> TrackingWorld:
        """The scene now."""
        return self._worlds[-1]

    @world.setter
    def world(self, world: TrackingWorld) -> None:
        with self._lock:
            if self.clock is None:              # private: no history to keep
                self._worlds[-1] = world
            else:
                self._times.append(self.now())
                self._worlds.append(world)

    def world_at(self, t: float) -> TrackingWorld:
        """The scene as it was at world time ``t`` (s): a ``SIM:LOAD`` replaces it from then on."""
        return self._worlds[bisect.bisect_right(self._times, t) - 1]

    def note_mirror(self, t: float, h: float, v: float) -> None:
        """The active mirror's Cardan angles ``(h, v)`` (rad) at world time ``t`` (s); kept for a shared world."""
        if self.clock is not None:
            with self._lock:
                self._mirror.append((t, h, v))

    def mirror_angles(self, times: ArrayLike) -> FloatArray:
        """Mirror angles ``(n, 2)`` rad at ``times`` (s), linear between the logged samples.

        ``(0, 0)`` (facing the camera: a fixed mirror) when no active mirror logged any.
        """
        t = np.atleast_1d(np.asarray(times, dtype=float))
        with self._lock:
            log = np.array(self._mirror, dtype=float).reshape(-1, 3)
        if not len(log):
            return np.zeros((t.size, 2))
        return np.stack([np.interp(t, log[:, 0], log[:, 1]), np.interp(t, log[:, 0], log[:, 2])], axis=1)

    def truth(self, times: ArrayLike) -> dict[str, FloatArray]:
        """Ground truth at ``times`` (s): see :func:`world_truth`, with the logged mirror angles."""
        t = np.atleast_1d(np.asarray(times, dtype=float))
        angles = self.mirror_angles(t)
        rows = [world_truth(self.world_at(float(tk)), float(tk), angles[k]) for k, tk in enumerate(t)]
        return {key: np.array([r[key] for r in rows]) for key in rows[0]} if rows else {}


class InWorld:
    """Mixin (before :class:`~mirrorlab.core.devices.LineSimulator`) of a simulator model that sees a
    :class:`SharedWorld` as ``self.scene`` and runs on its clock (:meth:`advance`).

    :attr:`world` is the scene now; setting it changes it for every simulator of the world.
    ``SIM:LOAD <scenario> <numbers...>`` sets it: the model's :meth:`scenario` says what a
    scenario loads (answering the usage :attr:`load_usage` to anything else), and the first
    sphere, the target, moves onto that path keeping its size and brightness
    (:func:`with_target`).
    """

    scene: SharedWorld
    clock_ms: float
    #: The scenarios of ``SIM:LOAD``, as its usage error names them.
    load_usage: ClassVar[str] = "SIM:LOAD <scenario> <numbers...>"

    def __init__(self, world: TrackingWorld | SharedWorld | None, default: Callable[[], TrackingWorld],
                 seed: int = 0) -> None:
        """See ``world`` if it is shared, else a private world of ``world`` or ``default()``; start at its time."""
        self.scene = world if isinstance(world, SharedWorld) else SharedWorld(world or default())
        super().__init__(seed)  # type: ignore[call-arg]  # the LineSimulator after this mixin
        self.clock_ms = self.scene.now() * 1000.0     # a shared world's clock; 0 for a private one

    def advance(self, seconds: float) -> None:
        """Advance the clock by ``seconds``; on a shared world up to the world's time instead (:meth:`SharedWorld.catch_up`)."""
        super().advance(self.scene.catch_up(seconds, self.clock_ms))  # type: ignore[misc]

    @property
    def world(self) -> TrackingWorld:
        """The scene (of the shared world, if any)."""
        return self.scene.world

    @world.setter
    def world(self, world: TrackingWorld) -> None:
        self.scene.world = world

    def scenario(self, kind: str, values: list[float], t0: float) -> Path | TrackingWorld | None:
        """What ``SIM:LOAD <kind> <values>`` loads at time ``t0`` (s): the target's new path, a whole new
        world, or ``None`` when it is not a scenario of this simulator (or has the wrong numbers)."""
        return None

    def cmd_SIM_LOAD(self, args: list[str]) -> Iterator[str]:
        """``SIM:LOAD <scenario> <numbers...>``: replace the target (see :meth:`scenario`)."""
        if not args:
            raise CommandError("E02", f"usage: {self.load_usage}")
        values = [LineSimulator.number(a, -1e6, 1e6, integer=False) for a in args[1:]]
        loaded = self.scenario(args[0].upper(), values, self.clock_ms / 1000.0)
        if loaded is None:
            raise CommandError("E02", f"usage: {self.load_usage}")
        self.world = loaded if isinstance(loaded, TrackingWorld) else with_target(self.world, loaded)
        yield "OK"


def with_target(world: TrackingWorld, path: Path) -> TrackingWorld:
    """``world`` with its target (the first sphere) on ``path``: its size, brightness and the rest unchanged.

    Examples
    --------
    >>> w = with_target(TrackingWorld(), Path((100.0, 0.0, 2000.0)))
    >>> w.target_position(0.0).tolist(), w.spheres[0].radius == TrackingWorld().spheres[0].radius
    ([100.0, 0.0, 2000.0], True)
    """
    return replace(world, spheres=(replace(world.spheres[0], path=path), *world.spheres[1:]))


def world_truth(world: TrackingWorld, t: float, mirror: ArrayLike = (0.0, 0.0)) -> dict[str, FloatArray]:
    """Truth of ``world`` at time ``t`` (s) with the mirror at Cardan angles ``mirror`` (rad).

    Returns ``target`` (mm), ``direction`` (unit vector from ``O`` to the target),
    ``target_angles`` (its ``(h, v)``, rad), ``mirror_angles`` (rad), ``normal`` (unit mirror
    normal) and ``in_mirror`` (the target's image, a disc of its radius, lies inside the mirror as
    the camera sees it, :func:`image_in_mirror`).

    Examples
    --------
    >>> w = TrackingWorld((Sphere(Path((3000.0, 0.0, 3000.0))),))
    >>> tr = world_truth(w, 0.0, (math.radians(22.5), 0.0))   # the normal bisects camera and target
    >>> bool(tr["in_mirror"]), bool(world_truth(w, 0.0)["in_mirror"])
    (True, False)
    """
    p = world.target_position(t)
    o = np.asarray(world.mirror_centre, dtype=float)
    h, v = (float(a) for a in np.asarray(mirror, dtype=float))
    normal = mirror_normal(h, v, world.camera_direction)
    return {"target": p, "direction": (p - o) / np.linalg.norm(p - o),
            "target_angles": np.array(world.target_angles(t)), "mirror_angles": np.array([h, v]),
            "normal": normal,
            "in_mirror": np.array(image_in_mirror(world.camera, p, o, normal, world.mirror_size,
                                                  world.spheres[0].radius))}


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
