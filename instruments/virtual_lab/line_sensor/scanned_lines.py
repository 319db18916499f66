"""What the simulators built on optical line detectors share: the line tracker, and the mirror
gimbal with a detector on each axis.

A scan's sample line leaves as soon as the scan takes it (:meth:`next_due_ms` wakes the server
then), the detector noise has its own generator (:class:`~..simulators.SeededNoise`), and the
optical faults (:data:`~.view.OPTICAL_FAULTS`) have their arguments checked before the simulator
records them.
"""

from __future__ import annotations

from mirrorlab.core.devices import CommandError

from ..simulators import SeededNoise
from ..world import InWorld
from .detector import Lines
from .view import OPTICAL_FAULTS, check_optical_fault


class ScannedLines(SeededNoise, InWorld):
    """Mixin of a :class:`~mirrorlab.core.devices.LineSimulator` model whose scans append stream
    lines to ``pending`` and schedule the next scan at ``next_sample_ms`` (device ms)."""

    pending: list[str]
    next_sample_ms: float

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
