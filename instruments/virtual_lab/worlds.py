"""A session's shared tracking world: the ``[world]`` keys, the preset scenes, and the truth in ``/truth/``.

A recipe's ``[world]`` table (or :meth:`mirrorlab.core.Session.set_world`) gives every simulated
tracker of the session (``ultrasonic_tracker``, ``line_tracker``, ``mirror_gimbal``: their
``world_parameters`` are :data:`TRACKING_WORLD`) one :class:`~.world.SharedWorld`: one target
trajectory, lamp, mirror and camera, on the session clock. When a recording stops,
:func:`record_world_truth` writes the world's ground truth at the camera's frame times under
``/truth/world`` (target position and direction, mirror angles and normal, whether the target's
image lies inside the mirror as the camera sees it).

World frame: right-handed, mm, ``y`` up; the mirror point ``O`` (and the trackers) at the origin,
looking along ``+z`` toward the scene; the camera on ``+z`` behind the scene, facing the mirror.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from mirrorlab.core import AlgorithmError, Parameter, ParameterSet

from .world import Path, SharedWorld, Sphere, TrackingWorld, mirror_normal, turntable_world

__all__ = ["SCENES", "TRACKING_WORLD", "TRUTH_STREAMS", "build_world", "latest_truth", "record_world_truth", "shared_world",
           "truth_arrays"]

#: The preset scenes of ``[world] scene``.
SCENES = ("still", "walk", "stage_line", "stage_ellipse", "turntable")
#: Key under which the session's :class:`~mirrorlab.core.devices.SimulatedWorld` keeps the shared world.
KEY = "tracking"

TRACKING_WORLD = ParameterSet(
    Parameter("scene", str, "still", choices=SCENES,
              help="still: a target at (azimuth, elevation); walk: from A to B across the room at speed; "
                   "stage_line / stage_ellipse: the x-y stage of Fig. 4.22; turntable: the disc of §3.4"),
    Parameter("range", float, 3000.0, unit="mm", bounds=(100.0, 100_000.0),
              help="distance ahead of the mirror point O (along +z) of the target or its path's centre"),
    Parameter("azimuth", float, 0.0, unit="rad", bounds=(-1.5, 1.5), help="still: target azimuth from +z"),
    Parameter("elevation", float, 0.0, unit="rad", bounds=(-1.5, 1.5), help="still: target elevation"),
    Parameter("width", float, 1000.0, unit="mm", bounds=(0.0, 100_000.0),
              help="walk: length A-B (centred on +z); stage: stroke or ellipse width; turntable: diameter"),
    Parameter("height", float, 0.0, unit="mm", bounds=(0.0, 100_000.0), help="stage_ellipse: ellipse height"),
    Parameter("speed", float, 800.0, unit="mm/s", bounds=(0.0, 100_000.0), help="walk: walking speed"),
    Parameter("period", float, 1.84, unit="s", bounds=(0.01, 3600.0), help="stage, turntable: seconds per cycle"),
    Parameter("start", float, 1.0, unit="s", bounds=(0.0, 1e6),
              help="session time at which the target starts moving (the loops settle before)"),
    Parameter("target_radius", float, 125.0, unit="mm", bounds=(1.0, 5000.0),
              help="radius of the target sphere (not the turntable's 150 mm disc)"),
    Parameter("brightness", float, 1.0, bounds=(0.0, 100.0), help="target reflectance (white = 1)"),
    Parameter("lamp", float, (0.0, 500.0, 500.0), unit="mm", shape=(3,),
              help="lamp position (not the turntable's, 2 m to the side)"),
    Parameter("camera_distance", float, 6000.0, unit="mm", bounds=(100.0, 100_000.0),
              help="camera on +z at this distance from O, facing the mirror"),
    Parameter("mirror_size", float, 1000.0, unit="mm", bounds=(1.0, 100_000.0), help="side of the square mirror"),
    Parameter("frame_rate", float, 24.0, unit="Hz", bounds=(0.1, 10_000.0),
              help="camera frames per second: /truth/world is written at these times"),
)

#: ``/truth/world/<name>``: (unit, description) of each quantity.
TRUTH_STREAMS = {
    "target": ("mm", "centre of the target"),
    "target_direction": ("", "unit vector from the mirror point O to the target"),
    "target_angles": ("rad", "(h, v) Cardan angles of the target direction from the camera direction"),
    "mirror_angles": ("rad", "(h, v) Cardan angles of the mirror normal (0, 0: facing the camera)"),
    "mirror_normal": ("", "unit normal of the mirror"),
    "in_mirror": ("", "the target's image (a disc of its radius) lies inside the mirror as the camera sees it"),
}


def build_world(settings: Mapping[str, Any]) -> TrackingWorld:
    """The :class:`TrackingWorld` of validated ``[world]`` settings (:data:`TRACKING_WORLD`).

    Examples
    --------
    >>> w = build_world({**TRACKING_WORLD.defaults(), "scene": "walk", "width": 4000.0, "speed": 1000.0})
    >>> [np.round(w.target_position(t), 3).tolist() for t in (0.0, 3.0, 9.0)]   # A, halfway, B
    [[-2000.0, 0.0, 3000.0], [0.0, 0.0, 3000.0], [2000.0, 0.0, 3000.0]]
    >>> w.camera
    (0.0, 0.0, 6000.0)
    """
    s = {**TRACKING_WORLD.defaults(), **settings}
    scene, r, start = s["scene"], s["range"], s["start"]
    camera = (0.0, 0.0, float(s["camera_distance"]))
    if scene == "turntable":
        base = turntable_world(s["width"] / 2.0, s["period"], r, start_s=start)
        return TrackingWorld(base.spheres, camera=camera, lamp=base.lamp, mirror_size=s["mirror_size"])
    rate = 2.0 * math.pi / s["period"]
    if scene == "still":
        path = Path(tuple(r * mirror_normal(s["azimuth"], s["elevation"], (0.0, 0.0, 1.0))))
    elif scene == "walk":
        half = s["width"] / 2.0
        duration = s["width"] / s["speed"] if s["speed"] > 0 else 0.0
        path = Path((-half, 0.0, r), (s["speed"], 0.0, 0.0), start_s=start, end_s=start + duration)
    elif scene == "stage_line":
        path = Path((0.0, 0.0, r), axes=((s["width"] / 2.0, 0.0, 0.0), (0.0, 0.0, 0.0)), rate=rate, start_s=start)
    elif scene == "stage_ellipse":
        path = Path((0.0, 0.0, r), axes=((s["width"] / 2.0, 0.0, 0.0), (0.0, s["height"] / 2.0, 0.0)), rate=rate,
                    phase=-math.pi / 2.0, start_s=start)
    else:
        raise ValueError(f"unknown world scene {scene!r}; use one of {', '.join(SCENES)}")
    sphere = Sphere(path, s["target_radius"], s["brightness"])
    return TrackingWorld((sphere,), camera=camera, lamp=tuple(float(x) for x in s["lamp"]),
                         mirror_size=s["mirror_size"])


def _build(settings: Mapping[str, Any], clock: Callable[[], float]) -> SharedWorld:
    values = TRACKING_WORLD.validate(dict(settings), where="world")
    return SharedWorld(build_world(values), clock)


def shared_world(world: Any) -> SharedWorld | None:
    """The :class:`SharedWorld` of a session's :class:`~mirrorlab.core.devices.SimulatedWorld` (``None``: none).

    The first tracker simulator of the session builds it from the world's settings; the others get
    the same object. Raises :class:`~mirrorlab.core.ValidationError` naming ``world.<key>`` for a bad setting.
    """
    return None if world is None else world.shared(KEY, _build)


def record_world_truth(session: Any) -> str | None:
    """Write the shared world's truth over the last recording to ``/truth/world`` (then ``world_2``...).

    Frames: the camera's (``frame_rate``) from the first to the last sample recorded by the world's
    simulated instruments, in session seconds. Each quantity of :data:`TRUTH_STREAMS` is a group
    with ``time`` (s) and ``data`` and the attributes ``unit``, ``time_unit``, ``description``,
    like a recorded stream. Returns the group path, or ``None`` without a shared world or samples.
    """
    spec = getattr(session, "world", None)
    shared = spec.get(KEY) if spec is not None else None
    if shared is None:
        return None
    ends: list[float] = []
    for label, inst in session.instruments.items():
        if type(inst).world_parameters is not TRACKING_WORLD:
            continue
        for stream in inst.streams():
            key = f"instruments/{label}/{stream.name}/time"
            if session.exists(key) and session.node(key).shape[0]:
                t = session.read(key)
                ends += [float(t.min()), float(t.max())]
    if not ends:
        return None
    rate = float(spec.settings.get("frame_rate", TRACKING_WORLD["frame_rate"].default))
    times = np.arange(math.ceil(min(ends) * rate), math.floor(max(ends) * rate) + 1) / rate
    if not times.size:
        return None
    truth = shared.truth(times)
    root, n = "truth/world", 1
    while session.exists(root):
        n += 1
        root = f"truth/world_{n}"
    world = shared.world
    session.write_group(root, {}, {"kind": "ground truth (shared tracking world)", "units": "mm, s, rad",
                                   "settings": {k: (list(v) if isinstance(v, tuple | list | np.ndarray) else v)
                                                for k, v in spec.settings.items()},
                                   "camera": list(world.camera), "mirror_centre": list(world.mirror_centre),
                                   "mirror_size": world.mirror_size, "target_radius": world.spheres[0].radius})
    names = {"target": "target", "target_direction": "direction", "target_angles": "target_angles",
             "mirror_angles": "mirror_angles", "mirror_normal": "normal", "in_mirror": "in_mirror"}
    for name, (unit, description) in TRUTH_STREAMS.items():
        session.write_group(f"{root}/{name}", {"time": times, "data": truth[names[name]]},
                            {"unit": unit, "time_unit": "s", "description": description})
    return "/" + root


def latest_truth(session: Any) -> str:
    """Path of the last ``/truth/world*`` group (one per recording) or an :class:`AlgorithmError`."""
    groups = sorted((k for k in session.members("truth") if k == "world" or k.startswith("world_")),
                    key=lambda k: int(k.partition("_")[2] or 1))
    if not groups:
        raise AlgorithmError(f"no /truth/world in {session.path}: give the recipe a [world] and record "
                             "(an acquire step) before this report")
    return f"truth/{groups[-1]}"


def truth_arrays(session: Any, root: str) -> dict[str, np.ndarray]:
    """``time`` and every quantity's ``data`` of a ``/truth/world`` group."""
    return {"time": session.read(f"{root}/target/time"),
            **{name: session.read(f"{root}/{name}/data") for name in session.members(root)}}
