"""``LineTrackerModel``: the simulated optical line-sensor direction detector (``kind = OLDT``, §3).

One :class:`~.detector.OpticalDetector` looking from ``mount`` along ``forward`` at a
:class:`TrackingWorld` (constructor argument, shareable). Every scan (``512 / clock`` s, 78.8 ms at
6.5 kHz) it sums the scene over the 49 deg across the sensor (:mod:`.view`), exposes, blurs, adds
noise, saturates (:mod:`.sensor`), binarises and picks a run; commands answer from the last scan.

Default world: the turntable of §3.4 - a 150 mm disc on a 160 mm radius turning in the plane
facing the detector 1 m away, 1.84 s per revolution, one lamp 2 m to the side (-x: the
low-pixel side is lit, as in Fig. 4.34).
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
from mirrorlab.core.devices import LineSimulator
from mirrorlab.instruments.virtual_lab.line_sensor.detector import OpticalDetector
from mirrorlab.instruments.virtual_lab.line_sensor.scanned_lines import ScannedLines
from mirrorlab.instruments.virtual_lab.line_sensor.sensor import FOCAL_MM, PITCH_MM, angle_to_pixel
from mirrorlab.instruments.virtual_lab.line_sensor.view import OPTICAL_FAULTS, detector_projection, optical_faults
from mirrorlab.instruments.virtual_lab.world import (
    Path,
    SharedWorld,
    TrackingWorld,
    axis_angles,
    turntable_world,
)

Lines = Iterator[str]
TURNTABLE = {"radius": 160.0, "period": 1.84, "range": 1000.0}


class LineTrackerModel(ScannedLines, LineSimulator):
    """Simulated OLDT detector.

    Parameters
    ----------
    world
        The scene (default :func:`turntable_world`), or a :class:`SharedWorld` that other
        simulators see too (then this simulator runs on the world's clock).
    seed
        Seed of the simulator's random generator.
    mount, forward
        Detector position (mm) and optical axis (unit vector); the sensor lies horizontal.
    """

    kind = "OLDT"
    model = "OLDT-512"
    firmware = "1.0"
    serial_number = "SIM0004"
    load_usage = "SIM:LOAD TURNTABLE <radius> <period_s> <range> | STILL <deg> <range> | LINE <x y z vx vy vz>"

    def __init__(self, world: TrackingWorld | SharedWorld | None = None, seed: int = 0,
                 mount: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 forward: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> None:
        self.mount = np.asarray(mount, dtype=float)
        self.forward = np.asarray(forward, dtype=float) / np.linalg.norm(forward)
        self.detector = OpticalDetector("M")
        self.pending: list[str] = []
        super().__init__(world, turntable_world, seed)
        self.next_sample_ms = self.clock_ms

    def reset(self) -> None:
        """Power-on: the detector's defaults, streams off."""
        super().reset()
        if hasattr(self, "detector"):
            self.detector.reset()
            self.pending = []

    @property
    def streaming(self) -> bool:
        return self.detector.streaming or bool(self.pending)

    @streaming.setter
    def streaming(self, on: bool) -> None:
        if hasattr(self, "detector"):
            self.detector.streaming = on

    def fault_names(self) -> tuple[str, ...]:
        return tuple(OPTICAL_FAULTS)

    # -- simulation --------------------------------------------------------------------------------
    def handle(self, line: str) -> Lines:
        words = self.words(line)
        name = self.handler_name(words[0]) if words else ""
        if name and hasattr(self.detector, name):
            return self.detector.handle(words)
        return super().handle(line)

    def signal(self, t: float) -> np.ndarray:
        """Video signal (counts) of a scan at world time ``t`` (s)."""
        faults = optical_faults(self.faults)
        proj = detector_projection(self.world, t, "H", 0.0, faults, eye=self.mount, reference=self.forward)
        return self.scan_signal(proj, self.detector.clock_hz, faults)

    def advance(self, seconds: float) -> None:
        """Advance the clock (a shared world's: up to its time), scanning every ``512 / clock`` s
        (plus ``TIMINGJITTER``)."""
        super().advance(seconds)
        while self.next_sample_ms <= self.clock_ms:
            t = self.next_sample_ms / 1000.0
            self.detector.sample(self.signal(t), int(round(t * 1000.0)))
            line = self.detector.stream_line()
            if line:
                self.pending.append(line)
            self.next_sample_ms += self.scan_period(self.detector.period_s) * 1000.0

    # -- scenarios and truth -------------------------------------------------------------------------
    def scenario(self, kind: str, values: list[float], t0: float) -> Path | TrackingWorld | None:
        """``SIM:LOAD TURNTABLE <radius mm> <period s> <range mm>`` | ``STILL <deg> <range mm>``
        | ``LINE <x> <y> <z> <vx> <vy> <vz>`` (world mm, mm/s): replace the target."""
        if kind == "TURNTABLE" and len(values) == 3 and values[1] > 0:
            return turntable_world(values[0], values[1], values[2], start_s=t0)
        if kind == "STILL" and len(values) == 2:
            a = math.radians(values[0])
            return Path(tuple(self.mount + values[1] * np.array([math.sin(a), 0.0, math.cos(a)])))
        if kind == "LINE" and len(values) == 6:
            return Path(tuple(values[:3]), tuple(values[3:]), start_s=t0)
        return None

    def truth_lines(self) -> list[str]:
        """``TIME <ms>``, ``TARGET <deg> <px>`` (true centre direction along the sensor and its pixel
        coordinate), ``SIZE <px>`` (true image diameter) and ``FAULT`` lines."""
        t = self.clock_ms / 1000.0
        v = self.world.target_position(t) - self.mount
        along, _ = axis_angles(v, self.forward)
        distance, radius = float(np.linalg.norm(v)), self.world.spheres[0].radius
        half = math.pi / 2 if distance <= radius else math.asin(radius / distance)   # reaching the detector: the field
        size = (math.tan(float(along) + half) - math.tan(float(along) - half)) * FOCAL_MM / PITCH_MM
        return [f"TIME {int(self.clock_ms)}",
                f"TARGET {self.fixed(math.degrees(float(along)), 4)} {float(angle_to_pixel(along)):.3f}",
                f"SIZE {size:.2f}", *self.fault_lines()]
