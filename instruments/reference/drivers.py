"""Drivers of the reference instruments (``ANGS`` angle source, ``ACTU`` actuator, ``CHNS`` chain source).

Each streams one tagged line type (:class:`~mirrorlab.core.devices.StreamingInstrument`: the reader
thread publishes each sample as it arrives, stamped with the device's own clock mapped to session
time, so a controller sees it without a further thread hop). Units at the API: seconds, radians,
hertz, millimetres.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np
from mirrorlab.core import DeviceError, Parameter, ParameterSet, StreamSpec
from mirrorlab.core.devices import SimulatedWorld, StreamingInstrument, StreamSample

from .models import ActuatorModel, AngleSourceModel, ChainSourceModel


class _StreamingInstrument(StreamingInstrument):
    """Streams ``!<tag> <µs> <fields>`` lines (by default one scalar in µrad, published in rad)."""

    tag: ClassVar[str]
    stream_name: ClassVar[str]
    stream_description: ClassVar[str]

    def apply_settings(self, settings: dict[str, Any]) -> None:
        self.query(f"RATE {settings['rate']:g}")

    def streams(self) -> list[StreamSpec]:
        return [StreamSpec(self.stream_name, "f8", (), "rad", self.settings["rate"], self.stream_description)]

    def parse_stream_line(self, line: str) -> list[StreamSample] | None:
        if not line.startswith(f"{self.tag} "):
            return None
        _, us, *fields = line.split()
        t = int(us) * 1e-6
        return [StreamSample(stream, t, value) for stream, value in self.parse_fields(fields).items()]

    def parse_fields(self, fields: list[str]) -> dict[str, Any]:
        """Stream name -> one sample's value from the fields after the time stamp (raises ValueError)."""
        (urad,) = fields
        return {self.stream_name: int(urad) * 1e-6}

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


class ChainSource(_StreamingInstrument):
    """A motion-capture source streaming the positions of a chain of joints (``CHNS``).

    The device streams the selected joints (``joints``, root to tip) once per frame; the stream
    ``joints`` holds one (joints, 3) array per frame in mm (NaN where a joint is missing) and
    ``frame`` the device's frame number. Its simulator plays a recording (``motion``: a BVH, C3D,
    TRC or TSV file, read by the plugin answering the ``mirrorlab_read_motion`` hook) or, without
    one, a generated arm (:func:`.chains.generated_arm`), looping.
    """

    name = "chain_source"
    version = "1.0.0"
    description = "Reference motion-capture source streaming joint positions (mm) of a chain, frame by frame"
    kind = "CHNS"
    simulator = ChainSourceModel
    tag = "J"
    stream_name = "joints"
    stream_description = "joint positions root to tip, mm"
    parameters = ParameterSet(
        Parameter("rate", float, 100.0, unit="Hz", bounds=(1.0, 1000.0), help="frames per second"),
        Parameter("joints", str, "shoulder,elbow,wrist,hand",
                  help="joints to stream, root to tip, comma-separated (JOINTS? lists the device's)"),
        Parameter("motion", str, "", path=True,
                  help="simulation only: the recording the simulator plays (.bvh, .c3d, .trc, .tsv; in a recipe "
                       "relative to the recipe's folder); empty = a generated arm"),
        Parameter("scale", float, 1.0, bounds=(0.0, None), help="simulation only: mm per unit of the recording"),
        Parameter("skip", int, 0, bounds=(0, None), help="simulation only: leading frames of the recording to drop"),
    )

    @property
    def joint_names(self) -> list[str]:
        return [j.strip() for j in self.settings["joints"].split(",") if j.strip()]

    @classmethod
    def make_simulator(cls, settings: Mapping[str, Any], seed: int,
                       world: SimulatedWorld | None = None) -> ChainSourceModel:
        """A simulator playing ``motion`` (or the generated arm) with the joints ``joints`` names (no part
        in a shared ``world``)."""
        from .chains import simulated_chain

        values = cls.parameters.validate(dict(settings))
        positions, names, rate = simulated_chain(values["motion"], [j.strip() for j in values["joints"].split(",")
                                                                     if j.strip()], values["scale"], values["skip"])
        return ChainSourceModel(positions, names, rate, seed=seed)

    def streams(self) -> list[StreamSpec]:
        rate = self.settings["rate"]
        return [StreamSpec("joints", "f8", (len(self.joint_names), 3), "mm", rate, self.stream_description),
                StreamSpec("frame", "i8", (), "", rate, "the device's frame number of each sample")]

    def apply_settings(self, settings: dict[str, Any]) -> None:
        super().apply_settings(settings)
        self.query("SEL " + " ".join(self.joint_names))

    def parse_fields(self, fields: list[str]) -> dict[str, Any]:
        n = len(self.joint_names)
        if len(fields) != 1 + 3 * n:
            raise ValueError(f"expected a frame number and {3 * n} coordinates, got {len(fields)} fields")
        xyz = np.array([float(v) for v in fields[1:]]).reshape(n, 3) * 1e-3
        return {"joints": xyz, "frame": int(fields[0])}

    def read(self) -> dict[str, np.ndarray]:
        raise DeviceError(f"{self.device_name} only streams; start acquiring and subscribe to 'joints'")
