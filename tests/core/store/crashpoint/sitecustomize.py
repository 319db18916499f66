"""Test-only: stop a real ``mirrorlab`` process at a named point, so that the crash matrix
(``tests/core/store/test_crash_matrix.py``) kills it exactly there. Never installed.

Python imports ``sitecustomize`` at start-up from ``PYTHONPATH``; the test puts this folder there
and sets ``MIRRORLAB_CRASH_AT`` to where the process stops:

* ``event:KIND`` — just after the session's event bus emits an event of that kind
  (``acquisition_started``, ``recording_started``), in the thread that emitted it;
* ``MODULE:QUALNAME:before`` or ``MODULE:QUALNAME:after`` — around a call of that function or method
  (as the caller looks it up: ``mirrorlab.core.compute:execute``);

with ``#N`` appended for the N-th time (default the first). There it writes the file
``MIRRORLAB_CRASH_MARK`` (the observable sign the test polls for) and waits forever.
"""

from __future__ import annotations

import functools
import importlib
import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

_SPEC = os.environ.get("MIRRORLAB_CRASH_AT", "")
_MARK = os.environ.get("MIRRORLAB_CRASH_MARK", "")


def _stop_here(where: str) -> None:
    Path(_MARK).write_text(f"{os.getpid()} {where}\n")
    threading.Event().wait()  # until the test's SIGKILL


def _counter(times: int, where: str) -> Callable[[], None]:
    seen = 0
    lock = threading.Lock()

    def tick() -> None:
        nonlocal seen
        with lock:
            seen += 1
            hit = seen == times
        if hit:
            _stop_here(where)
    return tick


def _install(spec: str) -> None:
    spec, _, nth = spec.partition("#")
    tick = _counter(int(nth or 1), spec)
    if spec.startswith("event:"):
        from mirrorlab.core.events import EventBus

        kind, emit = spec[len("event:"):], EventBus.emit

        @functools.wraps(emit)
        def emitting(self: EventBus, level: str, source: str, event_kind: str, message: str, **data: Any) -> Any:
            event = emit(self, level, source, event_kind, message, **data)
            if event_kind == kind:
                tick()
            return event
        EventBus.emit = emitting  # type: ignore[method-assign]
        return
    module_name, qualname, when = spec.split(":")
    owner: Any = importlib.import_module(module_name)
    *path, name = qualname.split(".")
    for part in path:
        owner = getattr(owner, part)
    original = owner.__dict__[name] if isinstance(owner, type) else getattr(owner, name)
    func = original.__func__ if isinstance(original, classmethod) else original

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        if when == "before":
            tick()
        result = func(*args, **kwargs)
        if when == "after":
            tick()
        return result
    setattr(owner, name, classmethod(wrapper) if isinstance(original, classmethod) else wrapper)


if _SPEC and _MARK:
    _install(_SPEC)
