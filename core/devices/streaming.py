"""Streaming line-protocol devices: samples as unsolicited lines, stamped by the device's clock.

A streaming device sends each sample as a ``!`` line stamped with its own clock (ms or µs since
power-up, spec ``instruments.md`` §0.2) while ``STREAM ON``. :class:`DeviceClock` turns those
stamps into session seconds, the one time base of a session, so that a sample's time says when
the device took it, not when the host got round to reading it: the latency a controller records
(``ack − sample time``) then counts the whole way from the device to the acknowledgement.
:class:`StreamingInstrument` is the base class of such drivers: it publishes each line as it
arrives and runs the stream's start, link check and stop.
"""

from __future__ import annotations

import threading
import time
from abc import abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import Any, NamedTuple, Protocol

import numpy as np

from ..errors import DeviceError, ProtocolError
from .instrument import Emit, Reporter, SerialInstrument
from .protocol import Reply


class _Queries(Protocol):
    def query(self, command: str, timeout: float | None = None) -> Reply: ...


class DeviceClock:
    """Maps a device's stamps (s since its power-up) to session time (s).

    :meth:`anchor` reads ``TIME?`` (whole ms since power-up, a counter: the true time lies half a
    millisecond past it on average) and takes it to hold at the midpoint of the query's round
    trip, so neither the reply's transit nor the counter's truncation makes samples look younger
    than they are. That leaves up to half a millisecond of doubt either way, so
    :meth:`session_time` also keeps every sample causal: a line cannot have been stamped after
    the host received it, and an offset that would say so is lowered to the tightest bound the
    stream has shown (the anchor only ever moves samples earlier, never later).

    Parameters
    ----------
    now
        The session clock (``emit.now``), s.

    Examples
    --------
    >>> t = iter([10.0, 10.002, 10.5])
    >>> clock = DeviceClock(lambda: next(t))
    >>> class Device:
    ...     def query(self, command, timeout=None):
    ...         return Reply(["4000"])          # TIME? -> 4000 ms since power-up
    >>> round(clock.anchor(Device()), 4)        # session time of device time 0, s
    6.0005
    >>> round(clock.session_time(4.4997), 4)    # a stamp received at 10.5 s: capped there
    10.5
    >>> round(clock.offset, 4)
    6.0003
    """

    def __init__(self, now: Callable[[], float]) -> None:
        self.now = now
        #: Session time of device time 0, s (``None`` before :meth:`anchor`).
        self.offset: float | None = None

    def anchor(self, device: _Queries) -> float:
        """Read ``TIME?`` from ``device`` and set :attr:`offset`; returns it (s).

        Call once per acquisition, after every (re)connect: a replugged device restarts its clock.
        """
        sent = self.now()
        ms = device.query("TIME?").field(0, "ms", float)
        self.offset = (sent + self.now()) / 2.0 - (ms + 0.5) / 1000.0
        return self.offset

    def session_time(self, device_s: float) -> float:
        """Session time (s) of a sample stamped ``device_s`` (s of device time) and received now.

        Raises :class:`RuntimeError` before :meth:`anchor` (a driver bug, not a device fault).
        """
        if self.offset is None:
            raise RuntimeError("DeviceClock.session_time() before anchor(): anchor when acquisition starts")
        self.offset = min(self.offset, self.now() - device_s)
        return device_s + self.offset


class StreamSample(NamedTuple):
    """One parsed stream line: which stream, when the device took it, what it measured."""

    stream: str
    #: Device time of the sample, s since the device's power-up.
    device_s: float
    #: One sample of the stream, in the shape its :class:`~mirrorlab.core.StreamSpec` declares.
    values: Any


class StreamingInstrument(SerialInstrument):
    """A line-protocol instrument whose samples arrive as unsolicited stream lines (``STREAM ON``).

    The base of every streaming driver: a subclass says how one ``!`` line reads
    (:meth:`parse_stream_line`) and, if it needs more than ``STREAM ON``, which commands start and
    stop its stream (:meth:`start_commands`, :meth:`stop_commands`); the class does the rest:

    * **acquire**: anchors the device clock (:class:`DeviceClock`, once per acquisition, so after
      every reconnect), sends the start commands, checks the link and caches the status every
      :attr:`~mirrorlab.core.devices.Instrument.status_interval` s (a dead link raises, and the base
      class reconnects), and sends the stop commands when acquisition ends, if the device is
      still reachable;
    * **publishing**: the protocol's reader thread parses each stream line and emits it at once,
      stamped with the device's own time mapped to session time (no queue, no further thread hop,
      so a controller sees the sample as soon as it arrives); lines before the clock is anchored
      or after acquisition ended are dropped, an unreadable line is a ``bad_sample`` warning, and
      every other ``!`` line goes to :meth:`SerialInstrument.on_unsolicited` (``!ERR`` reports).

    Example (``!T <ms> <mK>`` lines of a thermometer, stream ``temperature`` in K)::

        class Thermometer(StreamingInstrument):
            ...
            def parse_stream_line(self, line: str) -> StreamSample | None:
                if not line.startswith("T "):
                    return None
                _, ms, mk = line.split()   # a ValueError is reported as a bad sample
                return StreamSample("temperature", int(ms) / 1000.0, int(mk) / 1000.0)
    """

    def __init__(self, label: str, port: str | None = None, settings: Mapping[str, Any] | None = None,
                 timeout: float = 2.0, report: Reporter | None = None) -> None:
        super().__init__(label, port, settings, timeout, report)
        self._emit: Emit | None = None   # set while acquiring, with the clock anchored
        self._clock: DeviceClock | None = None

    @abstractmethod
    def parse_stream_line(self, line: str) -> StreamSample | Sequence[StreamSample] | None:
        """Read one ``!`` line (``!`` stripped): a :class:`StreamSample` (or several, for a line that
        carries a sample of several streams), or ``None`` if it is no stream line of this device.
        Raise :class:`ProtocolError` or :class:`ValueError` for a stream line that cannot be read.
        Runs in the protocol's reader thread: keep it quick."""

    def start_commands(self) -> tuple[str, ...]:
        """Commands that start the stream, in order, for the current settings (default ``STREAM ON``)."""
        return ("STREAM ON",)

    def stop_commands(self) -> tuple[str, ...]:
        """Commands that stop the stream when acquisition ends (default ``STREAM OFF``)."""
        return ("STREAM OFF",)

    def on_unsolicited(self, line: str) -> None:
        try:
            sample = self.parse_stream_line(line)
        except (ProtocolError, ValueError) as exc:
            self.report("warning", "bad_sample", f"{self.device_name}: unusable stream line {line[:60]!r} ({exc})")
            return
        if sample is None:
            super().on_unsolicited(line)
            return
        emit, clock = self._emit, self._clock
        if emit is not None and clock is not None:   # else: a line from before the anchor or after the stop
            for s in (sample,) if isinstance(sample, StreamSample) else sample:
                emit(s.stream, [clock.session_time(s.device_s)], np.asarray(s.values)[None])

    def acquire(self, emit: Emit, stop: threading.Event) -> None:
        clock = DeviceClock(getattr(emit, "now", time.monotonic))
        clock.anchor(self)    # a replugged device restarts its clock: anchor on every start
        self._clock, self._emit = clock, emit
        try:
            for command in self.start_commands():
                self.query(command)
            while not stop.wait(self.status_interval):
                self.last_status = self.status()   # a dead link raises here: the base class reconnects
        finally:
            self._emit = None
            if self.client is not None and self.client.alive:
                try:
                    for command in self.stop_commands():
                        self.query(command)
                except DeviceError:
                    pass   # stopping anyway; the next start configures the device afresh
