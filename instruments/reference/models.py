"""Simulators of the reference instruments (device models behind the line protocol).

``ANGS`` streams ``!A <µs> <µrad>``: a sinusoidal angle ``amplitude · sin(2π f t)`` sampled at
``RATE`` Hz. ``ACTU`` moves towards its target at a limited speed and streams
``!P <µs> <µrad>`` at ``RATE`` Hz; ``TGT <µrad>`` sets the target, ``HOLD`` keeps the present
position. ``CHNS`` plays a recorded chain (joint positions per frame, looping) and streams
``!J <µs> <frame> <x y z of each selected joint, µm>`` at ``RATE`` Hz, one frame per sample. Times
are the device clock in microseconds, angles integer microradians, positions integer micrometres.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Sequence

import numpy as np
from mirrorlab.core.devices import CommandError, Lines, LineSimulator
from numpy.typing import ArrayLike


class _Streaming(LineSimulator, ABC):
    """A device that streams one tagged sample line at ``RATE`` Hz."""

    tag = "X"

    def reset(self) -> None:
        super().reset()
        self.rate_hz = 100.0
        self._next_ms = 0.0

    @abstractmethod
    def sample(self, ms: float) -> str:
        """The fields of the sample streamed at device time ``ms``, after its time stamp."""

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
        behind = self.clock_ms - 100 * period - self._next_ms
        if behind > 0:  # after a pause, do not flood: the older samples are lost, and counted (!OVF)
            lost = int(behind // period) + 1
            self.skip_samples(lost)
            self.lost_lines += lost
            self._next_ms += lost * period
        while self._next_ms <= self.clock_ms:
            lines.append(f"!{self.tag} {int(round(self._next_ms * 1000))} {self.sample(self._next_ms)}")
            self._next_ms += period
        return lines

    def skip_samples(self, n: int) -> None:
        """``n`` samples are lost (not sent); a model whose samples advance something advances it."""

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

    def sample(self, ms: float) -> str:
        return str(int(round(self.amplitude_urad * math.sin(2 * math.pi * self.frequency_hz * ms / 1000.0))))

    def cmd_WAVE(self, args: list[str]) -> Lines:
        self.expect(args, 2, "WAVE <amplitude urad> <frequency Hz>")
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

    def sample(self, ms: float) -> str:
        return str(int(round(self.position)))

    def cmd_TGT(self, args: list[str]) -> Lines:
        self.expect(args, 1, "TGT <urad>")
        self.target = self.number(args[0], -self.limit_urad, self.limit_urad)
        self.holding = False
        yield f"OK {int(self.target)}"

    def cmd_TGT_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "TGT?")
        yield f"OK {int(round(self.target))}"   # after HOLD the target is the position: rounded as HOLD and POS?

    def cmd_SPEED(self, args: list[str]) -> Lines:
        self.expect(args, 1, "SPEED <urad/s>")
        self.speed = self.number(args[0], 1, 100_000_000, integer=False)
        yield f"OK {self.speed:g}"

    def cmd_HOLD(self, args: list[str]) -> Lines:
        self.expect(args, 0, "HOLD")
        self.target = self.position
        self.holding = True
        yield f"OK {int(round(self.position))}"

    def cmd_POS_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "POS?")
        yield f"OK {int(round(self.position))}"

    def truth_lines(self) -> list[str]:
        return [f"POS {self.fixed(self.position, 1)}", f"TGT {self.fixed(self.target, 1)}"]


class ChainSourceModel(_Streaming):
    """``CHNS``: plays recorded joint positions (a motion-capture system's live skeleton), looping.

    Parameters
    ----------
    positions : array_like (frames, joints, 3)
        Joint positions, mm; NaN where a joint is missing (streamed as ``nan``).
    names : sequence of str
        The joints' names (no spaces), in the order of ``positions``.
    frame_rate : float
        The recording's frame rate, Hz: the power-on ``RATE``.
    """

    kind = "CHNS"
    model = "CHAIN-SIM"
    serial_number = "CH0001"
    tag = "J"
    stream_tick = 0.001  # 120 Hz and faster

    def __init__(self, positions: ArrayLike, names: Sequence[str], frame_rate: float, seed: int = 0) -> None:
        self.positions = np.asarray(positions, float)
        self.names = [str(n) for n in names]
        if self.positions.ndim != 3 or self.positions.shape[1:] != (len(self.names), 3) or not len(self.positions):
            raise ValueError(f"positions must have shape (frames, {len(self.names)} joints, 3) mm, "
                             f"got {self.positions.shape}")
        if any(not n or " " in n for n in self.names):
            raise ValueError(f"joint names must be non-empty words without spaces, got {self.names}")
        self.frame_rate = float(frame_rate)
        super().__init__(seed)

    def reset(self) -> None:
        super().reset()
        self.rate_hz = self.frame_rate
        self.frame = 0                                  # next frame to stream
        self.selected = list(range(len(self.names)))

    def sample(self, ms: float) -> str:
        um = np.rint(self.positions[self.frame, self.selected] * 1000.0).ravel()
        fields = " ".join("nan" if v != v else str(int(v)) for v in um)
        line = f"{self.frame} {fields}"
        self.skip_samples(1)
        return line

    def skip_samples(self, n: int) -> None:
        """The recording plays on while samples are lost: their frames are skipped."""
        self.frame = (self.frame + n) % len(self.positions)

    def cmd_JOINTS_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "JOINTS?")
        yield "OK " + " ".join(self.names)

    def cmd_SEL(self, args: list[str]) -> Lines:
        if not args:
            raise CommandError("E02", "usage: SEL <joint> [<joint> ...]")
        unknown = [a for a in args if a not in self.names]
        if unknown:
            raise CommandError("E03", f"no joint {unknown[0]}; joints: {' '.join(self.names)}")
        self.selected = [self.names.index(a) for a in args]
        yield f"OK {len(self.selected)}"

    def cmd_SEL_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "SEL?")
        yield "OK " + " ".join(self.names[i] for i in self.selected)

    def cmd_FRAMES_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "FRAMES?")
        yield f"OK {len(self.positions)} {self.frame_rate:g}"

    def cmd_SEEK(self, args: list[str]) -> Lines:
        self.expect(args, 1, "SEEK <frame>")
        self.frame = int(self.number(args[0], 0, len(self.positions) - 1))
        yield f"OK {self.frame}"

    def truth_lines(self) -> list[str]:
        return [f"FRAME {self.frame}"]
