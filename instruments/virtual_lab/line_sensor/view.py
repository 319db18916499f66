"""What one line-sensor detector sees of a :class:`~mirrorlab.instruments.virtual_lab.world.TrackingWorld`.

The summing projection (§3.2) of the world's lit spheres and background onto the sensor axis of a
detector at the mirror point (plus an optional parallax offset), turned to ``angle`` about its
gimbal axis, with the optical faults of §3.5. Angles rad, lengths mm, signal counts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from mirrorlab.core.devices import CommandError, LineSimulator
from numpy.typing import ArrayLike, NDArray

from ..simulators import fault_usage
from ..world import TrackingWorld, axis_angles
from .sensor import FIELD_ACROSS, pixel_angles, sphere_projection

FloatArray = NDArray[np.float64]
PIXEL_ANGLES = pixel_angles()
#: Counts per unit projection (rad) and second of exposure: a white 250 mm ball 3 m away, lit by
#: the default lamp, peaks near 190 counts at 6.5 kHz. A simulator default, not from the thesis.
SIGNAL_GAIN = 2.0e4
AMBIENT = 1.0e-3               # projection of the black curtains (about 1.6 counts at 6.5 kHz)
MULTI_SPACING = 3.0              # centre spacing of MULTI markers, in angular radii of the target
BACKGROUND_IDS = (1, 2, 3)


@dataclass(frozen=True)
class OpticalFaults:
    """Optical faults of §3.5 (the ones that shape the scene; clock ones live in the host model).

    Attributes
    ----------
    background
        ``(profile id, gain)``: a low-frequency background fixed in the room (1 hump, 2 ramp,
        3 bright window), ``gain`` in counts at 6.5 kHz; the target occludes it.
    multi
        Extra identical markers beside the target, alternately on either side, 1.5 target
        diameters apart along the sensor.
    twopeak
        ``(separation rad, ratio)``: the target seen as two peaks of its own size (legs apart),
        ``separation`` apart, the second's radiance times ``ratio``.
    range_m
        The target's level as at this range (m) from the lamp and detector instead of 1 m:
        level times ``1 / range_m^2``, its size unchanged (threshold loss, §3.5).
    sidelight
        Lighting gradient across the target (run wider on the lit side).
    defocus_px
        Extra blur, px.
    saturate
        Exposure far above saturation (x 10).
    """

    background: tuple[int, float] | None = None
    multi: int = 0
    twopeak: tuple[float, float] | None = None
    range_m: float = 0.0
    sidelight: float = 0.0
    defocus_px: float = 0.0
    saturate: bool = False


#: The optical fault arguments that are integers (the others are numbers).
INTEGER_ARGUMENTS = frozenset({"profile_id", "n"})
#: The optical faults of §3.5 and their arguments (``SIM:FAULT <name> <args>``).
OPTICAL_FAULTS: dict[str, tuple[str, ...]] = {
    "BACKGROUND": ("profile_id", "gain"),
    "MULTI": ("n",),
    "TWOPEAK": ("separation_deg", "ratio"),
    "RANGE": ("m",),
    "SIDELIGHT": ("gradient",),
    "DEFOCUS": ("px",),
    "SATURATE": (),
    "TIMINGJITTER": ("ms",),
}


def check_optical_fault(name: str, values: list[str]) -> tuple[str, str] | None:
    """The ``(code, text)`` error for ``SIM:FAULT <name> <values>``, ``None`` if valid.

    Examples
    --------
    >>> check_optical_fault("TWOPEAK", ["12", "0.8"]) is None, check_optical_fault("BACKGROUND", ["9", "1"])
    (True, ('E03', 'background profile 9 unknown; use one of (1, 2, 3)'))
    """
    names = OPTICAL_FAULTS[name]
    if len(values) != len(names):
        return fault_usage(name, names)
    try:
        numbers = [LineSimulator.number(v, -1e6, 1e6, integer=n in INTEGER_ARGUMENTS) for v, n in zip(values, names)]
    except CommandError as exc:
        return exc.code, f"{name}: {exc.text}"
    if any(x < 0 for x in numbers):
        return "E03", f"{name} values must not be negative"
    if name == "BACKGROUND" and int(numbers[0]) not in BACKGROUND_IDS:
        return "E03", f"background profile {values[0]} unknown; use one of {BACKGROUND_IDS}"
    return None


def optical_faults(faults: dict[str, list[str]]) -> OpticalFaults:
    """The :class:`OpticalFaults` among a simulator's active ``SIM:FAULT`` values.

    Examples
    --------
    >>> optical_faults({"TWOPEAK": ["12", "0.8"], "SATURATE": []}).saturate
    True
    """
    def value(name: str, default: float = 0.0) -> float:
        v = faults.get(name)
        return float(v[0]) if v else default

    bg, tp = faults.get("BACKGROUND"), faults.get("TWOPEAK")
    return OpticalFaults(
        background=(int(bg[0]), float(bg[1])) if bg else None,
        multi=int(value("MULTI")),
        twopeak=(math.radians(float(tp[0])), float(tp[1])) if tp else None,
        range_m=value("RANGE"), sidelight=value("SIDELIGHT"), defocus_px=value("DEFOCUS"),
        saturate="SATURATE" in faults)


def background_profile(profile_id: int, world_angle: FloatArray) -> FloatArray:
    """Background shapes fixed in the room, as functions of the world angle along the sensor (rad).

    Examples
    --------
    >>> np.round(background_profile(1, np.array([0.0, 0.3])), 3).tolist()
    [1.0, 0.368]
    """
    if profile_id == 1:
        return np.exp(-(world_angle / 0.3) ** 2)
    if profile_id == 2:
        return np.clip(0.5 + world_angle, 0.0, 1.0)
    if profile_id == 3:
        return 1.0 / (1.0 + np.exp((np.abs(world_angle - 0.2) - 0.05) / 0.01))
    raise ValueError(f"background profile {profile_id} unknown; use one of {BACKGROUND_IDS}")


def detector_projection(world: TrackingWorld, t: float, axis: str, angle: float,
                        faults: OpticalFaults = OpticalFaults(), parallax_mm: float = 0.0,
                        eye: ArrayLike | None = None, reference: ArrayLike | None = None) -> FloatArray:
    """Summed radiance per pixel (rad) of the detector of gimbal ``axis`` (``"H"``/``"V"``) at ``angle``.

    The ``H`` detector's sensor lies along the azimuth (it sums over elevation), the ``V``
    detector's along the elevation. A sphere contributes when its direction lies within the
    49 deg summing range.

    Parameters
    ----------
    world
        The scene; spheres are lit by its lamp (``1/distance^2``).
    t
        World time, s.
    axis
        ``"H"`` or ``"V"``.
    angle
        Detector rotation from the camera direction about its axis, rad.
    faults
        Optical faults.
    parallax_mm
        Detector offset from the mirror point along the horizontal in-plane axis, mm.
    eye, reference
        A detector elsewhere: its position (mm) and the direction its ``angle`` is measured from
        (default: the mirror point and the camera direction, as on the gimbal).
    """
    base = np.asarray(world.mirror_centre if eye is None else eye, dtype=float)
    eye = base + np.array([parallax_mm, 0.0, 0.0])
    c = world.camera_direction if reference is None else np.asarray(reference, dtype=float)
    centres, halves, radiances = [], [], []
    for k, sphere in enumerate(world.spheres):
        p = sphere.path.position(t)
        u = p - eye
        distance = float(np.linalg.norm(u))
        level = sphere.brightness * world.lamp_factor(p)
        if k == 0 and faults.range_m > 0:
            level /= faults.range_m ** 2
        h, v = axis_angles(u, c)
        along, across = (float(h), float(v)) if axis == "H" else (float(v), float(h))
        if abs(across) > FIELD_ACROSS / 2:
            continue
        # a sphere that reaches the detector fills its field
        half = math.pi / 2 if distance <= sphere.radius else math.asin(sphere.radius / distance)
        copies = [(along - angle, level)]
        if k == 0 and faults.twopeak is not None:
            sep, ratio = faults.twopeak
            copies = [(along - angle - sep / 2, level), (along - angle + sep / 2, level * ratio)]
        if k == 0:  # identical markers alternately right and left, 1.5 diameters apart
            spacing = MULTI_SPACING * half
            copies += [(along - angle + (-1) ** n * (n // 2 + 1) * spacing, level) for n in range(faults.multi)]
        for centre, lvl in copies:
            centres.append(centre)
            halves.append(half)
            radiances.append(lvl)
    targets = sphere_projection(PIXEL_ANGLES, centres, halves, radiances, faults.sidelight) if centres \
        else np.zeros_like(PIXEL_ANGLES)
    background = np.full_like(PIXEL_ANGLES, AMBIENT)
    if faults.background is not None:
        pid, gain = faults.background
        exposure_6k5 = SIGNAL_GAIN * 512 / 6500.0
        background = background + gain / exposure_6k5 * background_profile(pid, PIXEL_ANGLES + angle)
    occluded = np.clip(targets / np.asarray(radiances).max() / FIELD_ACROSS, 0.0, 1.0) if centres else 0.0
    return targets + background * (1.0 - occluded)
