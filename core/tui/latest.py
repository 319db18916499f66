"""Latest-wins computation off the event loop, for screens whose input changes on every key press.

A screen :meth:`~LatestOnly.submit`\\ s each new input and starts a thread worker that calls
:meth:`~LatestOnly.run_pending`: it computes the newest input only (an input overtaken while a
computation runs is skipped, like the retargeting filter's single-slot input buffer) and never two
at once (the computation may keep state, e.g. a warm start).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Generic, TypeVar

Item = TypeVar("Item")
Result = TypeVar("Result")


class LatestOnly(Generic[Item, Result]):
    """Feed ``fn`` the newest submitted item, one call at a time.

    Examples
    --------
    >>> square = LatestOnly(lambda x: x * x)
    >>> square.submit(2); square.submit(3)
    >>> square.run_pending(), square.run_pending()
    (9, None)
    """

    def __init__(self, fn: Callable[[Item], Result]) -> None:
        self.fn = fn
        self._lock = threading.Lock()       # guards the slot
        self._busy = threading.Lock()       # one call of fn at a time
        self._pending: list[Item] = []

    def submit(self, item: Item) -> None:
        """Make ``item`` the newest input; an unread older one is dropped."""
        with self._lock:
            self._pending = [item]

    def run_pending(self) -> Result | None:
        """``fn`` of the newest input, or None when there is none (call it from a worker thread)."""
        with self._busy:
            with self._lock:
                pending, self._pending = self._pending, []
            return self.fn(pending[0]) if pending else None
