"""Structured events: the session log, warnings, progress.

Everything noteworthy — an instrument reconnecting, a queue overflow, an algorithm's progress, a
result written — is an :class:`Event`. The session's :class:`EventBus` stamps it with session
time, keeps it for the ``/log`` dataset and hands it to subscribers (the CLI's progress bar, the
TUI). Subscribers are called in the publishing thread and must return quickly.
"""

from __future__ import annotations

import json
import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

log = logging.getLogger("mirrorlab.events")

LEVELS = ("debug", "info", "warning", "error")


@dataclass(frozen=True)
class Event:
    """One structured event.

    Attributes
    ----------
    t
        Session time in seconds.
    level
        ``debug`` | ``info`` | ``warning`` | ``error``.
    source
        Who reports it: ``session``, ``recorder``, an instrument label, an algorithm name.
    kind
        Machine-readable type: ``reconnected``, ``overflow``, ``progress``, ``result_written``...
    message
        One human sentence.
    data
        JSON-able details (``{"done": 3, "total": 10}`` for progress).
    """

    t: float
    level: str
    source: str
    kind: str
    message: str
    data: dict[str, Any] = field(default_factory=dict)

    def data_json(self) -> str:
        return json.dumps(self.data, default=str, sort_keys=True)


Subscriber = Callable[[Event], None]


class EventBus:
    """Publish events to subscribers and keep them until the recorder stores them."""

    def __init__(self, clock: Any) -> None:
        self.clock = clock
        self._subs: list[Subscriber] = []
        self._pending: list[Event] = []
        self._lock = threading.Lock()

    def subscribe(self, fn: Subscriber) -> Callable[[], None]:
        """Add a subscriber; returns a function that removes it."""
        with self._lock:
            self._subs.append(fn)
        return lambda: self._remove(fn)

    def _remove(self, fn: Subscriber) -> None:
        with self._lock:
            if fn in self._subs:
                self._subs.remove(fn)

    def emit(self, level: str, source: str, kind: str, message: str, **data: Any) -> Event:
        if level not in LEVELS:
            raise ValueError(f"level must be one of {LEVELS}, not {level!r}")
        event = Event(self.clock.now(), level, source, kind, message, data)
        if kind != "progress":  # progress is live-only; the log keeps what happened
            getattr(log, level)("%s: %s", source, message)
            with self._lock:
                self._pending.append(event)
        with self._lock:
            subs = list(self._subs)
        for fn in subs:
            try:
                fn(event)
            except Exception:
                log.exception("event subscriber %r failed", fn)
        return event

    def progress(self, source: str, done: float, total: float | None, message: str = "") -> None:
        """Report progress of long work (``done`` of ``total`` units)."""
        self.emit("info", source, "progress", message, done=done, total=total)

    def take_pending(self) -> list[Event]:
        """Events not yet stored, oldest first (the recorder calls this)."""
        with self._lock:
            out, self._pending = self._pending, []
        return out
