"""Drivers of the reference instruments (``ANGS`` angle source, ``ACTU`` actuator).

Both stream one tagged line type (:class:`~mirrorlab.core.devices.StreamingInstrument`: the reader
thread publishes each sample as it arrives, stamped with the device's own clock mapped to session
time, so a controller sees it without a further thread hop). Units at the API: seconds, radians,
hertz.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
from mirrorlab.core import DeviceError, Parameter, ParameterSet, StreamSpec
from mirrorlab.core.devices import StreamingInstrument, StreamSample

from .models import ActuatorModel, AngleSourceModel


class _StreamingInstrument(StreamingInstrument):
    """Streams ``!<tag> <µs> <µrad>`` lines as one scalar stream in rad."""

    tag: ClassVar[str]
    stream_name: ClassVar[str]
    stream_description: ClassVar[str]

    def apply_settings(self, settings: dict[str, Any]) -> None:
        self.query(f"RATE {settings['rate']:g}")

    def streams(self) -> list[StreamSpec]:
        return [StreamSpec(self.stream_name, "f8", (), "rad", self.settings["rate"], self.stream_description)]

    def parse_stream_line(self, line: str) -> StreamSample | None:
        if not line.startswith(f"{self.tag} "):
            return None
        _, us, urad = line.split()
        return StreamSample(self.stream_name, int(us) * 1e-6, int(urad) * 1e-6)

    def read(self) -> dict[str, np.ndarray]:
        return {self.stream_name: np.array([self.query("POS?").field(0, "µrad", int) * 1e-6])}


class AngleSource(_StreamingInstrument):
    """A sensor streaming an angle (``ANGS``): the input of a closed loop."""

    name = "angle_source"
    version = "1.0.0"
    description = "Reference angle sensor streaming a sinusoidal angle (rad) at a set rate"
    kind = "ANGS"
    simulator = AngleSourceModel
    tag = "A"
    stream_name = "angle"
    stream_description = "measured angle, rad"
    parameters = ParameterSet(
        Parameter("rate", float, 100.0, unit="Hz", bounds=(1.0, 1000.0), help="samples per second"),
        Parameter("amplitude", float, 0.2, unit="rad", bounds=(0.0, math.pi), help="amplitude of the angle"),
        Parameter("frequency", float, 0.5, unit="Hz", bounds=(0.0, 100.0), help="frequency of the angle"),
    )

    def apply_settings(self, settings: dict[str, Any]) -> None:
        super().apply_settings(settings)
        self.query(f"WAVE {round(settings['amplitude'] * 1e6)} {settings['frequency']:g}")

    def read(self) -> dict[str, np.ndarray]:
        raise DeviceError(f"{self.device_name} only streams; start acquiring and subscribe to 'angle'")


class Actuator(_StreamingInstrument):
    """A rotary actuator with a live target angle (``ACTU``): the output of a closed loop."""

    name = "actuator"
    version = "1.0.0"
    description = "Reference rotary actuator: live target angle (rad), streams its position"
    kind = "ACTU"
    simulator = ActuatorModel
    tag = "P"
    stream_name = "position"
    stream_description = "actuator position, rad"
    parameters = ParameterSet(
        Parameter("rate", float, 50.0, unit="Hz", bounds=(1.0, 1000.0), help="position samples per second"),
        Parameter("speed", float, 2.0, unit="rad/s", bounds=(1e-6, 100.0), help="slew rate"),
        Parameter("target", float, 0.0, unit="rad", bounds=(-math.pi, math.pi), live=True,
                  help="angle to move to (a set-point)"),
    )

    def apply_settings(self, settings: dict[str, Any]) -> None:
        super().apply_settings(settings)
        self.query(f"SPEED {settings['speed'] * 1e6:g}")
        self.apply_setpoint("target", settings["target"], self.timeout)

    def apply_setpoint(self, name: str, value: Any, timeout: float) -> None:
        self.query(f"TGT {round(value * 1e6)}", timeout)

    def hold(self) -> None:
        self.query("HOLD")
