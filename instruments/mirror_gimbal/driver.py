"""``MirrorGimbal``: the active-mirror instrument plugin (``MGIM``, ``instruments.md`` §4.5).

Drives the two-axis gimbal over the line protocol. Settings choose each axis's mode (``track``:
the thesis's own loop (4.11)-(4.12); ``pos``: the mirror follows the live set-points
``h_angle``/``v_angle``; ``hold``; ``off``) and the loop settings. Streams ``h`` and ``v``: per
detector sample ``(K px, E px, mirror angle rad)``, NaN where the detector had no mark.
API units rad and s; the wire speaks degrees, ms, px and DAC counts.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import DeviceReplyError, Parameter, ParameterSet, ProtocolError, StreamSpec
from mirrorlab.core.devices import SimulatedWorld, StreamingInstrument, StreamSample
from mirrorlab.instruments.virtual_lab.line_sensor.sensor import MAX_CLOCK_HZ, MIN_CLOCK_HZ, PIXELS
from mirrorlab.instruments.virtual_lab.worlds import TRACKING_WORLD, shared_world

from .model import MirrorGimbalModel

AXES = ("h", "v")
LIMIT_RAD = math.radians(35.0)
#: The live set-point of each axis: the mirror angle it turns to in mode ``pos`` (declared ``live=True``
#: below). Set-points are looked up here, never parsed from their names.
POSITION_SETPOINTS = {"h": "h_angle", "v": "v_angle"}
#: Set-point -> the axis it turns.
SETPOINT_AXIS = {name: axis for axis, name in POSITION_SETPOINTS.items()}


def parse_sample(line: str) -> tuple[str, float, np.ndarray]:
    """``G <ms> <axis> <K> <E> <mirror deg>`` (``!`` stripped) -> (axis, device s, [K, E, rad]).

    Raises
    ------
    ProtocolError
        The line is not a gimbal sample.

    Examples
    --------
    >>> axis, t, v = parse_sample("G 1024 H 256.5 1.5 2.500")
    >>> axis, t, np.round(v, 6).tolist()
    ('h', 1.024, [256.5, 1.5, 0.043633])
    >>> parse_sample("G 1102 V - - -0.100")[2].tolist()[:2]
    [nan, nan]
    """
    parts = line.split(" ")
    if len(parts) != 6 or parts[0] != "G" or parts[2] not in ("H", "V"):
        raise ProtocolError(f"expected 'G <ms> <H|V> <K> <E> <deg>', got {line[:60]!r}")
    try:
        k, e = (float("nan") if p == "-" else float(p) for p in parts[3:5])
        return parts[2].lower(), int(parts[1]) / 1000.0, np.array([k, e, math.radians(float(parts[5]))])
    except ValueError:
        raise ProtocolError(f"malformed gimbal sample {line[:60]!r}") from None


class MirrorGimbal(StreamingInstrument):
    """Two-axis 1 m active mirror with a line-sensor detector per axis (MGIM)."""

    name = "mirror_gimbal"
    version = "1.0.0"
    description = "Two-axis 1 m active mirror, DC motors, a line-sensor detector per axis (MGIM)"
    kind = "MGIM"
    simulator = MirrorGimbalModel
    world_parameters = TRACKING_WORLD
    parameters = ParameterSet(
        Parameter("mode_h", str, "track", choices=("track", "pos", "hold", "off"),
                  help="horizontal axis: track = the detector loop (4.11)-(4.12), pos = follow h_angle"),
        Parameter("mode_v", str, "hold", choices=("track", "pos", "hold", "off"),
                  help="vertical axis (the thesis held it for a walking subject)"),
        Parameter("h_angle", float, 0.0, unit="rad", bounds=(-LIMIT_RAD, LIMIT_RAD), live=True,
                  help="horizontal mirror set-point in pos mode, from the camera direction"),
        Parameter("v_angle", float, 0.0, unit="rad", bounds=(-LIMIT_RAD, LIMIT_RAD), live=True,
                  help="vertical mirror set-point in pos mode"),
        Parameter("gain", float, 1.0, bounds=(0.0, 100.0), help="loop gain on E before (4.12); 1 = thesis"),
        Parameter("deadband", float, 0.0, bounds=(0.0, 127.5),
                  help="amplifier dead band around DAC 127.5, counts (0 = the thesis's dithering hardware)"),
        Parameter("limit", float, math.radians(30.0), unit="rad", bounds=(0.001, LIMIT_RAD),
                  help="software end stops of both axes at +-limit (mirror angle)"),
        Parameter("clock_hz", float, 6_500.0, unit="Hz", bounds=(MIN_CLOCK_HZ, MAX_CLOCK_HZ),
                  help="detector sensor clock: exposure and loop period 512 / clock"),
        Parameter("threshold", int, 128, bounds=(0, 255), help="detector comparator threshold, counts"),
    )

    @classmethod
    def make_simulator(cls, settings: Mapping[str, Any], seed: int,
                       world: SimulatedWorld | None = None) -> MirrorGimbalModel:
        """The simulator, in the session's shared ``world`` if it has one (else its own: a white 250 mm
        ball 3 m in front)."""
        return MirrorGimbalModel(shared_world(world), seed=seed)

    # -- settings ----------------------------------------------------------------------------------
    def apply_settings(self, settings: dict[str, Any]) -> None:
        limit = math.degrees(settings["limit"])
        self.query(f"H:CLK {int(round(settings['clock_hz']))}")
        for axis in AXES:
            a = axis.upper()
            self.query(f"GAIN {a} {settings['gain']:g}")
            self.query(f"DEADBAND {a} {settings['deadband']:g}")
            self.query(f"LIMIT {a} {-limit:.4f} {limit:.4f}")
            self.query(f"{a}:THR {settings['threshold']}")
            mode = settings[f"mode_{axis}"]
            if mode == "pos":
                name = POSITION_SETPOINTS[axis]
                self.apply_setpoint(name, settings[name], self.timeout)
            else:
                self.query(f"MODE {a} {mode.upper()}")

    def apply_setpoint(self, name: str, value: Any, timeout: float) -> None:
        """``POS <H|V> <deg>``: the mirror turns to ``value`` rad (mode POS); returns on the ``OK``."""
        self.query(f"POS {SETPOINT_AXIS[name].upper()} {math.degrees(value):.4f}", timeout)

    def hold(self) -> None:
        """Brake both axes at their present angles (``MODE <H|V> HOLD``)."""
        for axis in AXES:
            self.query(f"MODE {axis.upper()} HOLD")

    # -- streams -----------------------------------------------------------------------------------
    def streams(self) -> list[StreamSpec]:
        rate = self.settings["clock_hz"] / PIXELS
        return [StreamSpec(axis, "f8", (3,), "", rate,
                           f"{axis.upper()} axis per detector sample: K px, E = K - 255 px, mirror angle rad "
                           "(NaN K, E: no mark)") for axis in AXES]

    def parse_stream_line(self, line: str) -> StreamSample | None:
        if not line.startswith("G "):
            return None
        axis, t, row = parse_sample(line)
        return StreamSample(axis, t, row)

    def read(self) -> dict[str, np.ndarray]:
        """The last detector sample and mirror angle of each axis: ``{"h": (1, 3), "v": (1, 3)}``."""
        out = {}
        for axis in AXES:
            mirror, _ = self.angles(axis)
            try:
                k = self.query(f"SENS? {axis.upper()}").field(1, "K", float)
            except DeviceReplyError as exc:
                if exc.code not in ("E30", "E31"):
                    raise
                k = float("nan")
            out[axis] = np.array([[k, k - 255.0, mirror]])
        return out

    def angles(self, axis: str) -> tuple[float, float]:
        """``ANG?``: (mirror angle, detector angle) of ``axis`` (``"h"``/``"v"``), rad."""
        reply = self.query(f"ANG? {axis.upper()}")
        return math.radians(reply.field(0, "mirror deg", float)), math.radians(reply.field(1, "detector deg", float))
