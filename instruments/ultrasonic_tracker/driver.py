"""``UltrasonicTracker``: the ultrasonic direction tracker plugin (``USDF``, ``instruments.md`` §2.8).

Configures the step law, steering phase and random cycle period, switches the autonomous search
on (``TRACK ON``) and streams one row per search cycle: ``(theta1 rad, theta2 rad, mean pressure
counts, lost, end stop, quiet)``. API units rad and s; the wire speaks degrees and ms.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import DeviceReplyError, Parameter, ParameterSet, ProtocolError, StreamSpec
from mirrorlab.core.devices import SimulatedWorld, StreamingInstrument, StreamSample
from mirrorlab.instruments.virtual_lab.worlds import TRACKING_WORLD, shared_world

from .model import KH_DEFAULT, UltrasonicTrackerModel

FLAGS = "LEQ"


def parse_cycle(line: str) -> tuple[float, np.ndarray]:
    """``TRK <ms> <th1> <th2> <S> <flags>`` (``!`` stripped) -> (device s, [th1, th2 rad, S, L, E, Q]).

    Raises
    ------
    ProtocolError
        The line is not a search cycle.

    Examples
    --------
    >>> t, v = parse_cycle("TRK 2163 0.914 0.249 178.4 LQ")
    >>> t, np.round(v, 5).tolist()
    (2.163, [0.01595, 0.00435, 178.4, 1.0, 0.0, 1.0])
    """
    parts = line.split(" ")
    if len(parts) != 6 or parts[0] != "TRK" or not (parts[5] == "-" or set(parts[5]) <= set(FLAGS)):
        raise ProtocolError(f"expected 'TRK <ms> <th1> <th2> <S> <flags>', got {line[:60]!r}")
    try:
        th1, th2, s = (float(p) for p in parts[2:5])
        flags = [float(f in parts[5]) for f in FLAGS]
        return int(parts[1]) / 1000.0, np.array([math.radians(th1), math.radians(th2), s, *flags])
    except ValueError:
        raise ProtocolError(f"malformed search cycle {line[:60]!r}") from None


class UltrasonicTracker(StreamingInstrument):
    """12-element 40 kHz ultrasonic direction tracker on a two-axis servo platform (USDF)."""

    name = "ultrasonic_tracker"
    version = "1.0.0"
    description = "Ultrasonic direction tracker: 12-element 40 kHz array, gradient search (USDF)"
    kind = "USDF"
    simulator = UltrasonicTrackerModel
    world_parameters = TRACKING_WORLD
    parameters = ParameterSet(
        Parameter("psi", float, math.radians(45.0), unit="rad", bounds=(0.0, math.pi / 2),
                  help="steering phase step (45 deg deflects the beam about 7.5 deg)"),
        Parameter("step", float, math.radians(2.5), unit="rad", bounds=(0.0, math.radians(40.0)),
                  help="initial (longest) search step h0"),
        Parameter("step_gain", float, KH_DEFAULT, bounds=(0.0, 1e6),
                  help="Kh of h = min(h0, Kh / S), counts x deg (step inversely proportional to pressure)"),
        Parameter("rand_min", float, 0.012, unit="s", bounds=(0.001, 1.0), help="shortest random emission period"),
        Parameter("rand_max", float, 0.018, unit="s", bounds=(0.001, 1.0), help="longest random emission period"),
        Parameter("track", bool, True, help="run the autonomous search (TRACK ON) while acquiring"),
    )

    @classmethod
    def make_simulator(cls, settings: Mapping[str, Any], seed: int,
                       world: SimulatedWorld | None = None) -> UltrasonicTrackerModel:
        """The simulator, in the session's shared ``world`` if it has one (else its own: the 130 mm sphere 1.3 m ahead)."""
        return UltrasonicTrackerModel(shared_world(world), seed=seed)

    def apply_settings(self, settings: dict[str, Any]) -> None:
        if settings["rand_min"] > settings["rand_max"]:
            from mirrorlab.core.errors import Problem, ValidationError
            raise ValidationError([Problem(f"instruments.{self.label}.settings.rand_min",
                                           "rand_min must not exceed rand_max")])
        self.query(f"PSI {math.degrees(settings['psi']):.2f}")
        self.query(f"STEP {math.degrees(settings['step']):.4f} {settings['step_gain']:g}")
        self.query(f"RAND {settings['rand_min'] * 1000:g} {settings['rand_max'] * 1000:g}")

    def streams(self) -> list[StreamSpec]:
        return [StreamSpec("direction", "f8", (6,), "", 12.5,
                           "per search cycle: theta1 rad, theta2 rad, mean echo pressure counts, "
                           "lost, end stop, quiet (0/1)")]

    def parse_stream_line(self, line: str) -> StreamSample | None:
        if not line.startswith("TRK "):
            return None
        t, row = parse_cycle(line)
        return StreamSample("direction", t, row)

    def start_commands(self) -> tuple[str, ...]:
        return ("STREAM ON", "TRACK ON") if self.settings["track"] else ("STREAM ON",)

    def stop_commands(self) -> tuple[str, ...]:
        return ("TRACK OFF", "STREAM OFF")

    def read(self) -> dict[str, np.ndarray]:
        """One identification and measurement at the present aim: ``{"direction": (1, 6)}``."""
        th1, th2 = self.aim()
        try:
            self.query("IDENT", self.timeout + 1.0)
            pressures = self.measure()
            s, lost = float(np.mean(pressures)), 0.0
        except DeviceReplyError as exc:
            if exc.code not in ("E20", "E21"):
                raise
            s, lost = 0.0, 1.0
        return {"direction": np.array([[th1, th2, s, lost, 0.0, 0.0]])}

    def aim(self, theta1: float | None = None, theta2: float | None = None) -> tuple[float, float]:
        """``AIM`` (when angles are given, rad) or ``AIM?``: the platform set-point, rad (0.3125 deg steps)."""
        command = "AIM?" if theta1 is None else f"AIM {math.degrees(theta1):.4f} {math.degrees(theta2 or 0.0):.4f}"
        reply = self.query(command)
        return math.radians(reply.field(0, "th1", float)), math.radians(reply.field(1, "th2", float))

    def measure(self) -> np.ndarray:
        """``MEAS?``: the pressures ``(Sa, Sb, Sc, Sd)`` in counts at the identified echo time."""
        reply = self.query("MEAS?", self.timeout + 1.0)
        return np.array([reply.field(i, "pressure", float) for i in range(4)])
