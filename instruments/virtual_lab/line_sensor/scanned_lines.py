"""What the simulators built on optical line detectors share: the line tracker, and the mirror
gimbal with a detector on each axis.

A scan's sample line leaves as soon as the scan takes it (:meth:`next_due_ms` wakes the server
then), a scan's video signal is exposed, blurred and made noisy alike (:meth:`ScannedLines.scan_signal`)
and scans follow each other alike (:meth:`ScannedLines.scan_period`), the detector noise has its own
generator (:class:`~..simulators.SeededNoise`), and the optical faults
(:data:`~.view.OPTICAL_FAULTS`) have their arguments checked before the simulator records them.
"""

from __future__ import annotations

import math

import numpy as np
from mirrorlab.core.devices import CommandError
from numpy.typing import ArrayLike

from ..simulators import SeededNoise
from ..world import InWorld
from .detector import Lines
from .sensor import video_signal
from .view import OPTICAL_FAULTS, SIGNAL_GAIN, OpticalFaults, check_optical_fault

BLUR_PX = 1.5                    # deliberate defocus of the detector lens (§3.2), px
NOISE_COUNTS = 1.0               # sensor read noise, counts


class ScannedLines(InWorld, SeededNoise):
    """Mixin of a :class:`~mirrorlab.core.devices.LineSimulator` model whose scans append stream
    lines to ``pending`` and schedule the next scan at ``next_sample_ms`` (device ms)."""

    pending: list[str]
    next_sample_ms: float

    def scan_signal(self, projection: ArrayLike, clock_hz: float, faults: OpticalFaults) -> np.ndarray:
        """The video signal (counts) of one scan of ``projection`` at ``clock_hz`` (Hz): exposed (ten times
        over under ``SATURATE``), blurred by the lens (more under ``DEFOCUS``), with read noise."""
        gain = SIGNAL_GAIN * (10.0 if faults.saturate else 1.0)
        return video_signal(projection, clock_hz, gain, math.hypot(BLUR_PX, faults.defocus_px), NOISE_COUNTS,
                            self.np_rng)

    def scan_period(self, period_s: float) -> float:
        """Seconds to the next scan: ``period_s`` give or take a uniform draw within ``TIMINGJITTER`` ms, at least 1 ms."""
        jitter = self.np_rng.uniform(-1, 1) * self.fault_value("TIMINGJITTER") / 1000.0  # type: ignore[attr-defined]
        return max(1e-3, period_s + jitter)

    def stream_lines(self) -> list[str]:
        lines, self.pending = self.pending, []
        return lines

    def next_due_ms(self) -> float | None:
        """The next detector scan (device ms): its sample line leaves as soon as it is taken."""
        return self.next_sample_ms

    def cmd_SIM_FAULT(self, args: list[str]) -> Lines:
        if args and args[0].upper() in OPTICAL_FAULTS:
            problem = check_optical_fault(args[0].upper(), args[1:])
            if problem:
                raise CommandError(*problem)
        yield from super().cmd_SIM_FAULT(args)  # type: ignore[misc]
