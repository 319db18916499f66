"""Drivers of the reference instruments (``ANGS`` angle source, ``ACTU`` actuator).

Both stream one tagged line type; the reader thread publishes each sample as it arrives, stamped
with the device's own clock mapped to session time, so a controller sees it without a further
thread hop. Units at the API: seconds, radians, hertz.
"""

from __future__ import annotations

import math
import threading
from typing import Any, ClassVar

import numpy as np
from mirrorlab.core import DeviceError, Parameter, ParameterSet, StreamSpec
from mirrorlab.core.devices import DeviceClock, Emit, SerialInstrument

from .models import ActuatorModel, AngleSourceModel


class _StreamingInstrument(SerialInstrument):
    """Streams ``!<tag> <µs> <µrad>`` lines as one scalar stream in rad."""

    tag: ClassVar[str]
    stream_name: ClassVar[str]
    stream_description: ClassVar[str]

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._emit: Emit | None = None
        self._clock: DeviceClock | None = None

    def apply_settings(self, settings: dict[str, Any]) -> None:
        self.query(f"RATE {settings['rate']:g}")

    def streams(self) -> list[StreamSpec]:
        return [StreamSpec(self.stream_name, "f8", (), "rad", self.settings["rate"], self.stream_description)]

    def on_unsolicited(self, line: str) -> None:
        emit, clock = self._emit, self._clock
        if not line.startswith(f"{self.tag} ") or emit is None or clock is None:
            super().on_unsolicited(line)
            return
        try:
            _, us, urad = line.split()
            t, value = int(us) * 1e-6, int(urad) * 1e-6
        except ValueError:
            self.report("warning", "bad_sample", f"{self.device_name}: unusable stream line {line!r}")
            return
        emit(self.stream_name, [clock.session_time(t)], [value])

    def acquire(self, emit: Emit, stop: threading.Event) -> None:
        # The device clock anchored to session time once per acquisition (a replug restarts it).
        self._clock = DeviceClock(emit.now)
        self._clock.anchor(self)
        self._emit = emit
        self.query("STREAM ON")
        try:
            while not stop.wait(self.status_interval):
                self.last_status = self.status()  # a dead link raises here: the base class reconnects
        finally:
            self._emit = None
            if self.client is not None and self.client.alive and not stop.is_set():
                try:
                    self.query("STREAM OFF")
                except DeviceError:
                    pass

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
