"""``OpticalDetector``: the OLDT command set of one line-sensor direction detector (``instruments.md`` §3.6).

The detector's state (threshold, clock, selection rule, adaptive threshold, last sample) and its
command handlers. It does not own a scene: its host model (the gimbal simulator, one detector per
axis) renders the scene's projection and calls :meth:`OpticalDetector.sample` once per scan; the
handlers then answer from that sample. Handlers follow :class:`LineSimulator`'s convention
(``cmd_<WORD>`` generators, :class:`CommandError` for ``ERR``) so a host dispatches ``H:THR 120`` to
``cmd_THR(["120"])``.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from mirrorlab.core.devices import CommandError, LineSimulator
from mirrorlab.core.devices.wire import encode_bits

from .sensor import MAX_CLOCK_HZ, MIN_CLOCK_HZ, PIXELS, SATURATION, adapt_threshold, find_runs, mark_of_run, select_run

Lines = Iterator[str]
RULES = ("WIDEST", "NEAREST", "FIRST")


@dataclass(frozen=True)
class Mark:
    """One sample's result: time (ms), position ``m`` (px), size ``d`` (px), threshold, run count.

    ``error`` is ``None`` for a valid mark, else the ``(code, text)`` ``MARK?`` answers.
    """

    ms: int
    m: float
    d: int
    threshold: int
    nruns: int
    error: tuple[str, str] | None = None

    @property
    def valid(self) -> bool:
        return self.error is None

    def fields(self) -> str:
        """``<ms> <m> <d> <T> <nruns>`` as on the wire (``-`` for no mark)."""
        m, d = (f"{self.m:.1f}", str(self.d)) if self.valid else ("-", "-")
        return f"{self.ms} {m} {d} {self.threshold} {self.nruns}"


def clock_argument(args: list[str]) -> float:
    """The sensor clock (Hz) of ``CLK <Hz>``: a line sensor read by the 6502 host loop (this detector's and
    the film scanner's), which cannot keep up above :data:`~.sensor.MAX_CLOCK_HZ`.

    Examples
    --------
    >>> clock_argument(["73000"])
    73000.0
    """
    LineSimulator.expect(args, 1, "CLK <Hz>")
    hz = LineSimulator.number(args[0], MIN_CLOCK_HZ, 5_000_000)
    if hz > MAX_CLOCK_HZ:
        raise CommandError("E03", f"{hz} Hz: the host loop cannot keep up above {MAX_CLOCK_HZ} Hz")
    return float(hz)


def threshold_argument(args: list[str]) -> int:
    """The comparator threshold (counts) of ``THR <0-255>``.

    Examples
    --------
    >>> threshold_argument(["120"])
    120
    """
    LineSimulator.expect(args, 1, "THR <0-255>")
    return int(LineSimulator.number(args[0], 0, 255))


class OpticalDetector:
    """State and OLDT commands of one detector; :meth:`sample` processes one scan.

    Parameters
    ----------
    prefix
        Stream-line tag: ``"M"`` standalone, ``"H:M"`` / ``"V:M"`` through a gimbal.
    """

    def __init__(self, prefix: str = "M") -> None:
        self.prefix = prefix
        self.reset()

    def reset(self) -> None:
        """Power-on state: 6.5 kHz clock, threshold 128, widest run, fixed threshold, no stream."""
        self.clock_hz = 6_500.0
        self.threshold = 128
        self.rule = "WIDEST"
        self.auto = "OFF"
        self.auto_step = 4
        self.d_ref = 0
        self.streaming = False
        self.signal = np.zeros(PIXELS)
        self.runs = np.zeros((0, 2), dtype=np.int64)
        self.mark = Mark(0, 0.0, 0, self.threshold, 0, ("E30", "no mark"))
        self.previous_m: float | None = None

    @property
    def period_s(self) -> float:
        """Sampling period = one scan, ``512 / clock`` s (78.8 ms at 6.5 kHz)."""
        return PIXELS / self.clock_hz

    def sample(self, signal: np.ndarray, ms: int) -> Mark:
        """Binarise one scan's video ``signal`` (counts), pick the run, adapt the threshold."""
        self.signal = signal
        self.runs = find_runs(signal > self.threshold)
        index = select_run(self.runs, self.rule, self.previous_m)
        n = len(self.runs)
        if index is None:
            error = ("E30", "no mark") if n == 0 else ("E31", "multiple: runs tie for the widest")
            self.mark = Mark(ms, 0.0, 0, self.threshold, n, error)
            if self.auto == "ON" and n == 0:        # d = 0 < d_ref: lower the threshold (Step 4)
                self.threshold = adapt_threshold(self.threshold, 0, self.d_ref, self.auto_step)
            return self.mark
        e1, e2 = self.runs[index]
        m, d = mark_of_run(self.runs[index])
        saturated = bool((signal[e1:e2 + 1] >= SATURATION).any())
        self.mark = Mark(ms, m, d, self.threshold, n, ("E32", "saturated") if saturated else None)
        self.previous_m = m
        if self.auto == "ON":
            self.threshold = adapt_threshold(self.threshold, d, self.d_ref, self.auto_step)
        elif self.auto == "MODEL":
            self.threshold = self._model_threshold(e1, e2, d)
        return self.mark

    def _model_threshold(self, e1: int, e2: int, d: int) -> int:
        # Size-threshold relation from the profile itself: d shrinks by 2 px per |slope| counts.
        slope = np.abs(np.gradient(self.signal))[[max(e1 - 1, 0), min(e2 + 1, PIXELS - 1)]].mean()
        return int(np.clip(round(self.threshold + slope * (d - self.d_ref) / 2.0), 0, 255))

    def stream_line(self) -> str | None:
        """``!<prefix> <ms> <m> <d> <T> <nruns>`` for the last sample, when streaming."""
        return f"!{self.prefix} {self.mark.fields()}" if self.streaming else None

    # -- OLDT commands (§3.6) ------------------------------------------------------------------------
    def handle(self, words: list[str]) -> Lines:
        handler = getattr(self, LineSimulator.handler_name(words[0]), None)
        if handler is None:
            raise CommandError("E01", f"unknown detector command {words[0]}")
        return handler(words[1:])

    def cmd_CLK(self, args: list[str]) -> Lines:
        self.clock_hz = clock_argument(args)
        yield f"OK {int(self.clock_hz)} {self.period_s * 1000:.1f}"

    def cmd_THR(self, args: list[str]) -> Lines:
        self.threshold = threshold_argument(args)
        yield f"OK {self.threshold}"

    def cmd_THR_Q(self, args: list[str]) -> Lines:
        LineSimulator.expect(args, 0, "THR?")
        yield f"OK {self.threshold}"

    def cmd_FRAME_Q(self, args: list[str]) -> Lines:
        LineSimulator.expect(args, 0, "FRAME?")
        yield f"F {self.mark.ms} {encode_bits(self.signal > self.mark.threshold)}"
        yield "OK"

    def cmd_GREY_Q(self, args: list[str]) -> Lines:
        LineSimulator.expect(args, 0, "GREY?")
        grey = np.clip(np.floor(self.signal), 0, 255).astype(int)
        yield f"GREY {self.mark.ms} {' '.join(map(str, grey))}"
        yield "OK"

    def cmd_MARK_Q(self, args: list[str]) -> Lines:
        LineSimulator.expect(args, 0, "MARK?")
        if self.mark.error is not None:
            raise CommandError(*self.mark.error)
        yield f"OK {self.mark.fields()}"

    def cmd_RUNS_Q(self, args: list[str]) -> Lines:
        LineSimulator.expect(args, 0, "RUNS?")
        for e1, e2 in self.runs:
            yield f"RUN {e1} {e2}"
        yield f"OK {len(self.runs)}"

    def cmd_AUTO(self, args: list[str]) -> Lines:
        usage = "AUTO ON <dT> <d_ref> | OFF | MODEL"
        if not args or args[0].upper() not in ("ON", "OFF", "MODEL"):
            raise CommandError("E02", f"usage: {usage}")
        mode = args[0].upper()
        if mode == "ON":
            LineSimulator.expect(args, 3, usage)
            self.auto_step = int(LineSimulator.number(args[1], 1, 255))
            self.d_ref = int(LineSimulator.number(args[2], 1, PIXELS))
        else:
            LineSimulator.expect(args, 1, usage)
            if mode == "MODEL" and self.d_ref == 0:
                self.d_ref = self.mark.d if self.mark.valid else 0
                if self.d_ref == 0:
                    raise CommandError("E30", "no mark: AUTO MODEL takes d_ref from the current mark")
        self.auto = mode
        yield "OK"

    def cmd_SELECT(self, args: list[str]) -> Lines:
        self.rule = LineSimulator.keyword(args, f"SELECT {'|'.join(RULES)}")
        yield "OK"

    def cmd_STREAM(self, args: list[str]) -> Lines:
        self.streaming = LineSimulator.keyword(args, "STREAM ON|OFF") == "ON"
        yield "OK"
