"""Streaming line-protocol devices: the device clock of their stream lines, mapped to session time.

A streaming device stamps each ``!`` line with its own clock (ms or µs since power-up, spec
``instruments.md`` §0.2). :class:`DeviceClock` turns those stamps into session seconds, the one
time base of a session, so that a sample's time says when the device took it, not when the host
got round to reading it: the latency a controller records (``ack − sample time``) then counts the
whole way from the device to the acknowledgement.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol

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
