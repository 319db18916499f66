"""Immutable summaries of a live session, for UIs and scripts (:meth:`Session.snapshot`).

A snapshot is built from values the session's threads already keep in memory: it never calls a
device and never touches the HDF5 file, so a UI can take one at 50 Hz or more while a device is
busy in a long command or the recorder is writing. Times are session seconds; sizes are bytes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from .controller_runtime import ControllerState, LatencyStats
from .devices.instrument import InstrumentState, Status


@dataclass(frozen=True)
class InstrumentSnapshot:
    """One instrument.

    Attributes
    ----------
    label, plugin
        Its label in the session and its plugin name.
    state
        ``idle``, ``connecting``, ``acquiring``, ``reconnecting``, ``failed`` or ``stopped``
        (an :class:`~mirrorlab.core.devices.InstrumentState`, equal to those strings).
    acquiring, recorded
        Whether it is started, and whether the current recording includes it.
    last_sample_time
        Session time of its newest sample, s (``None`` before the first).
    samples, dropped, reconnects
        Of the current (or last) recording: samples queued for the file, samples dropped because
        the recorder could not keep up, reconnections.
    reconnect_seconds_left
        While ``reconnecting``: seconds left in its reconnect budget (``None``: no limit or not
        reconnecting).
    status
        The last :class:`Status` its acquisition thread cached (``None`` before the first).
    error
        Why it failed (``""`` if it did not).
    """

    label: str
    plugin: str
    state: InstrumentState
    acquiring: bool
    recorded: bool
    last_sample_time: float | None
    samples: int
    dropped: int
    reconnects: int
    reconnect_seconds_left: float | None
    status: Status | None
    error: str


@dataclass(frozen=True)
class ControllerSnapshot:
    """One controller: ``state`` (a :class:`~mirrorlab.core.controller_runtime.ControllerState`:
    ``idle``, ``running``, ``failed``, ``stopped``), commands sent and failed, latency statistics (s)
    of its recent set-points, and why it failed (``""``); ``superseded_commands``: values given to
    ``ctx.send`` that a newer one replaced before they were sent."""

    label: str
    plugin: str
    state: ControllerState
    commands: int
    failed_commands: int
    latency: LatencyStats | None
    error: str
    superseded_commands: int = 0


@dataclass(frozen=True)
class RecorderSnapshot:
    """The recorder: ``queue`` blocks waiting (of ``capacity``), ``bytes_written`` to the file in
    this recording, and its ``error`` (``""`` unless it failed, e.g. a full disk)."""

    recording: bool
    queue: int
    capacity: int
    bytes_written: int
    error: str


@dataclass(frozen=True)
class SessionSnapshot:
    """The whole session at session time ``t`` (s); mappings are read-only, keyed by label."""

    t: float
    path: str
    acquiring: bool
    recording: bool
    recording_seconds: float
    instruments: Mapping[str, InstrumentSnapshot]
    controllers: Mapping[str, ControllerSnapshot]
    recorder: RecorderSnapshot
