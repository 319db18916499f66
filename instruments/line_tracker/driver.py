"""``LineTracker``: the optical line-sensor direction detector plugin (``OLDT``, ``instruments.md`` §3.6).

Sets the clock (exposure and period), threshold, run selection and adaptive threshold, and streams
one row per scan: ``(m px, d px, threshold, runs)`` with NaN ``m``, ``d`` when there was no mark.
``direction(m)`` converts a position to the angle along the sensor (rad).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import DeviceReplyError, Parameter, ParameterSet, ProtocolError, StreamSpec
from mirrorlab.core.devices import SimulatedWorld, StreamingInstrument, StreamSample
from mirrorlab.instruments.virtual_lab.line_sensor.sensor import CENTRE_PX, FOCAL_MM, MAX_CLOCK_HZ, MIN_CLOCK_HZ, PITCH_MM, PIXELS
from mirrorlab.instruments.virtual_lab.worlds import TRACKING_WORLD, shared_world

from .model import LineTrackerModel


def parse_mark(line: str, tag: str = "M") -> tuple[float, np.ndarray]:
    """``<tag> <ms> <m> <d> <T> <nruns>`` (``!`` stripped) -> (device s, [m, d, T, nruns]).

    Raises
    ------
    ProtocolError
        The line is not a mark.

    Examples
    --------
    >>> parse_mark("M 945 255.5 92 128 1")
    (0.945, array([255.5,  92. , 128. ,   1. ]))
    >>> parse_mark("M 1024 - - 40 0")[1].tolist()
    [nan, nan, 40.0, 0.0]
    """
    parts = line.split(" ")
    if len(parts) != 6 or parts[0] != tag:
        raise ProtocolError(f"expected '{tag} <ms> <m> <d> <T> <nruns>', got {line[:60]!r}")
    try:
        m, d = (float("nan") if p == "-" else float(p) for p in parts[2:4])
        return int(parts[1]) / 1000.0, np.array([m, d, float(int(parts[4])), float(int(parts[5]))])
    except ValueError:
        raise ProtocolError(f"malformed mark {line[:60]!r}") from None


def direction(m: float) -> float:
    """Angle along the sensor (rad) of position ``m`` (px): ``arctan((m - 255.5) * 0.028 / 44)``.

    Examples
    --------
    >>> round(math.degrees(direction(506.9)), 2)
    9.09
    """
    return math.atan((m - CENTRE_PX) * PITCH_MM / FOCAL_MM)


class LineTracker(StreamingInstrument):
    """Cylindrical-lens 512-pixel line-sensor direction detector (OLDT)."""

    name = "line_tracker"
    version = "1.0.0"
    description = "Optical direction detector: cylindrical lens and 512-pixel line sensor (OLDT)"
    kind = "OLDT"
    simulator = LineTrackerModel
    world_parameters = TRACKING_WORLD
    parameters = ParameterSet(
        Parameter("clock_hz", float, 6_500.0, unit="Hz", bounds=(MIN_CLOCK_HZ, MAX_CLOCK_HZ),
                  help="sensor clock: exposure and sampling period 512 / clock (78.8 ms at 6.5 kHz)"),
        Parameter("threshold", int, 128, bounds=(0, 255), help="comparator threshold T0, counts"),
        Parameter("select", str, "widest", choices=("widest", "nearest", "first"),
                  help="run selection: widest, nearest to the previous mark, first"),
        Parameter("auto", str, "off", choices=("off", "on", "model"),
                  help="adaptive threshold (Steps 1-5): on = step dT toward d_ref, model = from the profile"),
        Parameter("auto_step", int, 4, bounds=(1, 255), help="dT of the adaptive threshold, counts"),
        Parameter("d_ref", int, 100, bounds=(1, PIXELS), help="reference mark size of the adaptive threshold, px"),
    )

    @classmethod
    def make_simulator(cls, settings: Mapping[str, Any], seed: int, world: SimulatedWorld | None = None) -> LineTrackerModel:
        """The simulator, in the session's shared ``world`` if it has one (else its own: the turntable of §3.4)."""
        return LineTrackerModel(shared_world(world), seed=seed)

    def apply_settings(self, settings: dict[str, Any]) -> None:
        self.query(f"CLK {int(round(settings['clock_hz']))}")
        self.query(f"THR {settings['threshold']}")
        self.query(f"SELECT {settings['select'].upper()}")
        if settings["auto"] == "on":
            self.query(f"AUTO ON {settings['auto_step']} {settings['d_ref']}")
        else:
            self.query(f"AUTO {settings['auto'].upper()}")

    def streams(self) -> list[StreamSpec]:
        return [StreamSpec("mark", "f8", (4,), "", self.settings["clock_hz"] / PIXELS,
                           "per scan: position m px, size d px, threshold counts, runs (NaN m, d: no mark)")]

    def parse_stream_line(self, line: str) -> StreamSample | None:
        if not line.startswith("M "):
            return None
        t, row = parse_mark(line)
        return StreamSample("mark", t, row)

    def read(self) -> dict[str, np.ndarray]:
        """The last scan's mark: ``{"mark": (1, 4)}`` (NaN ``m``, ``d`` without a mark)."""
        try:
            reply = self.query("MARK?")
            values = [reply.field(i, "mark", float) for i in range(1, 5)]
        except DeviceReplyError as exc:
            if exc.code not in ("E30", "E31", "E32"):
                raise
            values = [float("nan"), float("nan"), float(self.query("THR?").field(0, "T", int)), float("nan")]
        return {"mark": np.array([values])}

    def runs(self) -> np.ndarray:
        """``RUNS?``: every run of the last scan, ``(n, 2)`` inclusive pixel edges."""
        reply = self.query("RUNS?")
        try:
            edges = [[int(x) for x in line.split(" ")[1:3]] for line in reply.data]
        except ValueError:
            raise ProtocolError(f"{self.device_name}: malformed RUN line in {reply.data[:2]}") from None
        if len(edges) != reply.field(0, "n", int) or any(not line.startswith("RUN ") for line in reply.data):
            raise ProtocolError(f"{self.device_name}: RUNS? sent {len(edges)} RUN lines, not {reply.fields[0]}")
        return np.array(edges, dtype=np.int64).reshape(-1, 2)
