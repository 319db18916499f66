"""What :meth:`Instrument.set <mirrorlab.core.devices.Instrument.set>` returns: one set-point in flight.

In the spirit of ophyd-async's ``AsyncStatus``, for threads instead of coroutines: ``set`` validates
the value and returns at once; the instrument's set-point thread sends it, and the
:class:`SetStatus` says when the device acknowledged it (or why not)::

    status = actuator.set("target", "5 deg")   # returns at once
    status.wait(timeout=2.0)                   # the applied value, rad; raises the device's error
    status.done, status.success, status.latency

``set(...).wait()`` is the blocking call that ``set`` was before.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from ..errors import DeviceTimeout


class SetStatus:
    """One set-point sent to a device: pending, then acknowledged or failed.

    Parameters
    ----------
    device
        How error messages name the instrument (:attr:`Instrument.device_name`).
    name
        The live parameter being set.
    value
        The value as validated, in the parameter's unit: what the device is told.
    """

    def __init__(self, device: str, name: str, value: Any) -> None:
        self.device = device
        self.name = name
        #: The value as validated, in the parameter's unit (what :meth:`wait` returns once acknowledged).
        self.value = value
        self._started = time.monotonic()
        self._latency: float | None = None
        self._exception: BaseException | None = None
        self._done = threading.Event()
        self._lock = threading.Lock()  # callbacks added while the status finishes run once
        self._callbacks: list[Callable[[SetStatus], None]] = []

    def __repr__(self) -> str:
        if not self.done:
            outcome = "pending"
        elif self._exception is not None:
            outcome = f"failed: {self._exception!r}"
        else:
            outcome = f"acknowledged in {self._latency:.3g} s"
        return f"<SetStatus {self.device}: {self.name} = {self.value!r}, {outcome}>"

    @property
    def done(self) -> bool:
        """Whether the device acknowledged the set-point or it failed."""
        return self._done.is_set()

    @property
    def success(self) -> bool:
        """Whether the device acknowledged it (``False`` while pending)."""
        return self.done and self._exception is None

    @property
    def exception(self) -> BaseException | None:
        """Why it failed (a :class:`~mirrorlab.core.errors.DeviceError` from the device, ...); ``None``
        while pending or once acknowledged."""
        return self._exception if self.done else None

    @property
    def latency(self) -> float | None:
        """Seconds from the call to ``set`` to the acknowledgement or the failure (``None`` while pending)."""
        return self._latency

    def wait(self, timeout: float | None = None) -> Any:
        """Wait until done; return :attr:`value` once acknowledged, raise the :attr:`exception` if it failed.

        Parameters
        ----------
        timeout
            Seconds to wait at most (``None``: until done, which the instrument's own command timeout
            bounds).

        Raises
        ------
        DeviceTimeout
            Not done within ``timeout`` s; the set-point is still in flight (wait again, or check
            :attr:`done` later).
        """
        if not self._done.wait(timeout):
            raise DeviceTimeout(f"{self.device}: {self.name} = {self.value} was not acknowledged within {timeout:g} s "
                                "(still in flight)")
        if self._exception is not None:
            raise self._exception
        return self.value

    def add_callback(self, callback: Callable[[SetStatus], None]) -> None:
        """Call ``callback(status)`` once done: in the instrument's set-point thread, or now if done already."""
        with self._lock:
            if not self.done:
                self._callbacks.append(callback)
                return
        callback(self)

    def finish(self, exception: BaseException | None = None) -> list[Exception]:
        """Mark it acknowledged (or failed with ``exception``) and run the callbacks; called once, by the
        thread that sent it. Returns what the callbacks raised (each runs, whatever the others do)."""
        with self._lock:
            self._latency = time.monotonic() - self._started
            self._exception = exception
            self._done.set()
            callbacks, self._callbacks = self._callbacks, []
        errors = []
        for callback in callbacks:
            try:
                callback(self)
            except Exception as exc:  # the sender reports it; the next callback still runs
                errors.append(exc)
        return errors
