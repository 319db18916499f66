"""Simulators of the reference instruments (device models behind the line protocol).

``ANGS`` streams ``!A <µs> <µrad>``: a sinusoidal angle ``amplitude · sin(2π f t)`` sampled at
``RATE`` Hz. ``ACTU`` moves towards its target at a limited speed and streams
``!P <µs> <µrad>`` at ``RATE`` Hz; ``TGT <µrad>`` sets the target, ``HOLD`` keeps the present
position. Times are the device clock in microseconds, angles integer microradians.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

from mirrorlab.core.devices import Lines, LineSimulator


class _Streaming(LineSimulator, ABC):
    """A device that streams one tagged sample line at ``RATE`` Hz."""

    tag = "X"

    def reset(self) -> None:
        super().reset()
        self.rate_hz = 100.0
        self._next_ms = 0.0

    @abstractmethod
    def value_urad(self, ms: float) -> int:
        """The streamed value at device time ``ms``, µrad."""

    def cmd_RATE(self, args: list[str]) -> Lines:
        self.expect(args, 1, "RATE <Hz>")
        self.rate_hz = self.number(args[0], 1, 1000, integer=False)
        yield f"OK {self.rate_hz:g}"

    def cmd_STREAM(self, args: list[str]) -> Lines:
        yield from super().cmd_STREAM(args)
        self._next_ms = self.clock_ms  # a stream starts now, not with the samples missed while off

    def next_due_ms(self) -> float | None:
        """The next sample's device time while streaming: it leaves at that moment."""
        return self._next_ms if self.streaming else None

    def stream_lines(self) -> list[str]:
        lines = []
        period = 1000.0 / self.rate_hz
        self._next_ms = max(self._next_ms, self.clock_ms - 100 * period)  # after a pause, do not flood
        while self._next_ms <= self.clock_ms:
            lines.append(f"!{self.tag} {int(round(self._next_ms * 1000))} {self.value_urad(self._next_ms)}")
            self._next_ms += period
        return lines

    def fault_names(self) -> tuple[str, ...]:
        return ()


class AngleSourceModel(_Streaming):
    """``ANGS``: a sinusoidal angle, streamed."""

    kind = "ANGS"
    model = "ANGLE-SIM"
    serial_number = "AS0001"
    tag = "A"

    def reset(self) -> None:
        super().reset()
        self.amplitude_urad = 200_000  # 0.2 rad
        self.frequency_hz = 0.5

    def value_urad(self, ms: float) -> int:
        return int(round(self.amplitude_urad * math.sin(2 * math.pi * self.frequency_hz * ms / 1000.0)))

    def cmd_WAVE(self, args: list[str]) -> Lines:
        self.expect(args, 2, "WAVE <amplitude µrad> <frequency Hz>")
        self.amplitude_urad = int(self.number(args[0], 0, 3_141_593))
        self.frequency_hz = self.number(args[1], 0, 100, integer=False)
        yield f"OK {self.amplitude_urad} {self.frequency_hz:g}"

    def truth_lines(self) -> list[str]:
        return [f"WAVE {self.amplitude_urad} {self.frequency_hz:g}"]


class ActuatorModel(_Streaming):
    """``ACTU``: moves towards its target at ``SPEED`` µrad/s, streams its position."""

    kind = "ACTU"
    model = "ACTUATOR-SIM"
    serial_number = "AC0001"
    tag = "P"
    limit_urad = 3_141_593

    def reset(self) -> None:
        super().reset()
        self.rate_hz = 50.0
        self.position = 0.0  # µrad
        self.target = 0.0
        self.speed = 2_000_000.0  # µrad/s
        self.holding = False

    @property
    def state(self) -> str:
        return "HOLD" if self.holding else "MOVE" if abs(self.target - self.position) > 0.5 else "IDLE"

    def advance(self, seconds: float) -> None:
        step = self.speed * seconds
        self.position += max(-step, min(step, self.target - self.position))
        super().advance(seconds)

    def value_urad(self, ms: float) -> int:
        return int(round(self.position))

    def cmd_TGT(self, args: list[str]) -> Lines:
        self.expect(args, 1, "TGT <µrad>")
        self.target = self.number(args[0], -self.limit_urad, self.limit_urad)
        self.holding = False
        yield f"OK {int(self.target)}"

    def cmd_TGT_Q(self, args: list[str]) -> Lines:
        yield f"OK {int(self.target)}"

    def cmd_SPEED(self, args: list[str]) -> Lines:
        self.expect(args, 1, "SPEED <µrad/s>")
        self.speed = self.number(args[0], 1, 100_000_000, integer=False)
        yield f"OK {self.speed:g}"

    def cmd_HOLD(self, args: list[str]) -> Lines:
        self.target = self.position
        self.holding = True
        yield f"OK {int(round(self.position))}"

    def cmd_POS_Q(self, args: list[str]) -> Lines:
        yield f"OK {int(round(self.position))}"

    def truth_lines(self) -> list[str]:
        return [f"POS {self.position:.1f}", f"TGT {self.target:.1f}"]
