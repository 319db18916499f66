"""The typed instrument base classes: the top of the transport / protocol / instrument stack.

An instrument plugin subclasses :class:`Instrument` (any frame source, camera, file reader) or
:class:`SerialInstrument` (a device speaking the line protocol of ``instruments.md`` §0.2) and
declares, as class attributes, what the framework needs to generate CLI options, validate recipes,
build TUI forms and run the conformance kit::

    class Thermometer(SerialInstrument):
        name = "thermometer"
        version = "1.0.0"
        description = "Serial thermometer"
        parameters = ParameterSet(Parameter("rate", float, 10.0, unit="Hz", bounds=(0.1, 100)))
        simulator = ThermometerModel          # a LineSimulator subclass

Lifecycle: ``connect → identify → configure → streams → start(emit) … stop → close``; ``read``
and ``status`` may be called any time after ``connect``. Every call is bounded by ``timeout``.
While started, :meth:`acquire` runs in the instrument's own thread; when it raises
:class:`DeviceDisconnected`, :class:`DeviceTimeout` or :class:`ProtocolError` the base class
reports it, reconnects with exponential backoff (if the device allows) and resumes — other
instruments of the session keep recording meanwhile. Any other :class:`MirrorlabError` (damaged
data: :class:`DataError`; a device's ``ERR`` reply) stops that instrument, reported once.
"""

from __future__ import annotations

import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from ..errors import (
    DeviceDisconnected,
    DeviceError,
    DeviceTimeout,
    MirrorlabError,
    PluginError,
    Problem,
    ProtocolError,
    ValidationError,
)
from ..params import ParameterSet
from ..streams import StreamSpec
from .protocol import LineClient, Reply
from .simulator import LineSimulator
from .transport import open_port

#: Called by an instrument to report something: ``report(level, kind, message, **data)``.
Reporter = Callable[..., None]
#: Handed to :meth:`Instrument.acquire`: ``emit(stream, times_s, values)``.
Emit = Callable[[str, Any, Any], None]


def _log_report(level: str, kind: str, message: str, **data: Any) -> None:
    import logging

    getattr(logging.getLogger("mirrorlab.instrument"), level)("%s: %s", kind, message)


@dataclass(frozen=True)
class Identity:
    """What ``*IDN?`` (or a non-serial source) says the device is."""

    kind: str
    vendor: str
    model: str
    firmware: str
    serial: str

    def as_dict(self) -> dict[str, str]:
        return {"kind": self.kind, "vendor": self.vendor, "model": self.model,
                "firmware": self.firmware, "serial": self.serial}


@dataclass(frozen=True)
class Status:
    """A snapshot of an instrument's state (``STAT?`` plus the framework's counters)."""

    state: str
    flags: tuple[str, ...] = ()
    connected: bool = True
    detail: dict[str, Any] = field(default_factory=dict)


class Instrument(ABC):
    """Base class of every instrument plugin.

    Parameters
    ----------
    label
        The instrument's name in the session (``"cam"``); the HDF5 group ``/instruments/<label>``.
    port
        Where the device is (a pyserial URL or path, a folder, a camera index...), or ``None``
        when the settings say it.
    settings
        Values for :attr:`parameters`; validated at construction.
    timeout
        Seconds allowed for any one call to the device.
    report
        Callback for events (the session connects this to its event log).
    """

    name: ClassVar[str]
    version: ClassVar[str]
    description: ClassVar[str]
    parameters: ClassVar[ParameterSet] = ParameterSet()
    simulator: ClassVar[type[LineSimulator] | None] = None
    supports_reconnect: ClassVar[bool] = True
    max_backoff: ClassVar[float] = 5.0

    def __init__(self, label: str, port: str | None = None, settings: Mapping[str, Any] | None = None,
                 timeout: float = 2.0, report: Reporter | None = None) -> None:
        self.label = label
        self.port = port
        self.timeout = timeout
        self.settings: dict[str, Any] = self.parameters.validate(dict(settings or {}),
                                                                 where=f"instruments.{label}.settings")
        self.report: Reporter = report or _log_report
        self.identity: Identity | None = None
        self.reconnects = 0
        self.failed: BaseException | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._set_lock = threading.Lock()  # one set-point at a time, whichever thread sends it

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.label!r} port={self.port!r}>"

    @property
    def device_name(self) -> str:
        """How error messages name this device."""
        where = f" on {self.port}" if self.port else ""
        return f"{self.name} {self.label!r}{where}"

    # -- the device API (subclasses implement) ----------------------------------------------------
    @abstractmethod
    def connect(self) -> None:
        """Open the connection (idempotent). Raises :class:`DeviceDisconnected` if impossible."""

    @abstractmethod
    def identify(self) -> Identity:
        """Ask the device who it is; stores and returns :attr:`identity`."""

    @abstractmethod
    def apply_settings(self, settings: dict[str, Any]) -> None:
        """Send validated settings to the device (called by :meth:`configure` and on reconnect)."""

    @abstractmethod
    def streams(self) -> list[StreamSpec]:
        """The streams :meth:`acquire` will emit, given the current settings."""

    @abstractmethod
    def acquire(self, emit: Emit, stop: threading.Event) -> None:
        """Acquire until ``stop`` is set, calling ``emit(stream, times, values)``.

        Runs in the instrument's own thread. Times are session seconds (use ``emit.now()``).
        """

    @abstractmethod
    def read(self) -> dict[str, np.ndarray]:
        """One on-demand reading of every stream (outside recording)."""

    @abstractmethod
    def status(self) -> Status:
        """Current state, flags and counters."""

    @abstractmethod
    def close(self) -> None:
        """Stop acquisition and release the device (idempotent)."""

    # -- shared behaviour ----------------------------------------------------------------------------
    @classmethod
    def needs_port(cls, settings: Mapping[str, Any]) -> bool:
        """Whether these settings need a ``port`` when not simulated (recipes check it)."""
        return False

    @classmethod
    def make_simulator(cls, settings: Mapping[str, Any], seed: int) -> LineSimulator:
        """The device model a simulated instance with these ``settings`` talks to.

        Called by :meth:`mirrorlab.core.Session.add_instrument` (``simulate=True``), recipes
        (``simulate = true``) and the conformance kit; the session serves the model on a pty or
        TCP socket and the driver talks to it like to the real device. ``seed`` makes its noise
        reproducible. The default builds :attr:`simulator` (``cls.simulator(seed=seed)``);
        override it when the model depends on the settings (the film scanner films the scene
        or images its settings name).

        Raises
        ------
        PluginError
            The plugin ships no simulator.
        """
        if cls.simulator is None:
            raise PluginError(f"instrument plugin {cls.name!r} has no simulator; set simulate = false "
                              "and give the port of a real device")
        return cls.simulator(seed=seed)

    @classmethod
    def has_simulator(cls) -> bool:
        """Whether :meth:`make_simulator` can build a model: :attr:`simulator` is set or it is overridden."""
        return cls.simulator is not None or cls.make_simulator.__func__ is not Instrument.make_simulator.__func__

    def configure(self, **changes: Any) -> dict[str, Any]:
        """Validate ``changes`` against :attr:`parameters`, apply them, return all settings."""
        merged = {**self.settings, **changes}
        self.settings = self.parameters.validate(merged, where=f"instruments.{self.label}.settings")
        self.apply_settings(self.settings)
        return dict(self.settings)

    def set(self, name: str, value: Any, timeout: float | None = None) -> Any:
        """Change one live-settable parameter (a set-point) and return when the device acknowledged it.

        Only ``name`` is validated (against its declaration and the other current settings) and
        sent; nothing else is re-sent. Safe to call from any thread, also while acquiring.

        Parameters
        ----------
        name
            A parameter declared with ``live=True``.
        value
            New value, in the parameter's unit (or a ``"<number> <unit>"`` string).
        timeout
            Seconds allowed for the acknowledgement (default: the instrument's ``timeout``).

        Returns the value as validated and applied.
        """
        if name not in self.parameters:
            raise ValidationError([Problem(f"instruments.{self.label}.{name}",
                                           f"{self.name} has no parameter {name!r}")])
        if not self.parameters[name].live:
            live = [p.name for p in self.parameters if p.live]
            raise ValidationError([Problem(f"instruments.{self.label}.{name}",
                                           "not live-settable; change it with configure() "
                                           f"(live-settable: {', '.join(live) or 'none'})")])
        settings = self.parameters.validate({**self.settings, name: value},
                                            where=f"instruments.{self.label}.settings")
        with self._set_lock:
            self.apply_setpoint(name, settings[name], self.timeout if timeout is None else timeout)
            self.settings[name] = settings[name]
        return settings[name]

    def apply_setpoint(self, name: str, value: Any, timeout: float) -> None:
        """Send one validated live parameter and wait up to ``timeout`` s for the acknowledgement.

        Instruments with ``live=True`` parameters override this; the base class has none.
        """
        raise DeviceError(f"{self.device_name} declares {name!r} live but does not implement apply_setpoint()")

    def hold(self) -> None:
        """Stop moving and keep the present position (told when a controller commanding this
        instrument fails). Instruments that move override it; a sensor has nothing to hold."""
        return None

    def metadata(self) -> dict[str, Any]:
        """Plugin, version, settings and identity: stored as the instrument group's attributes."""
        return {
            "plugin": self.name,
            "version": self.version,
            "description": self.description,
            "port": self.port or "",
            "identity": self.identity.as_dict() if self.identity else {},
        }

    def __enter__(self) -> Instrument:
        self.connect()
        self.identify()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
        self.close()

    def start(self, emit: Emit) -> None:
        """Start :meth:`acquire` in the instrument's thread (reconnecting on connection loss)."""
        if self._thread is not None and self._thread.is_alive():
            raise DeviceError(f"{self.device_name} is already started; stop it first")
        self._stop.clear()
        self.failed = None
        self._thread = threading.Thread(target=self._run, args=(emit,), name=f"acquire {self.label}",
                                         daemon=True)
        self._thread.start()

    def stop(self, timeout: float | None = None) -> None:
        """Ask the acquisition thread to stop and wait for it (idempotent)."""
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=timeout if timeout is not None else self.timeout + 5.0)
            if thread.is_alive():
                self.report("error", "stop_timeout",
                            f"{self.device_name}: acquisition did not stop within the timeout")
        self._thread = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def reconnect(self) -> None:
        """Close, connect, identify and re-apply settings."""
        self.close()
        self.connect()
        self.identify()
        self.apply_settings(self.settings)

    def _run(self, emit: Emit) -> None:
        while not self._stop.is_set():
            try:
                self.acquire(emit, self._stop)
                return
            except (DeviceDisconnected, DeviceTimeout, ProtocolError) as exc:
                if self._stop.is_set():
                    return
                self.report("warning", "connection_lost", f"{self.device_name}: {exc}")
                if not self.supports_reconnect or not self._reconnect_with_backoff():
                    self.failed = exc
                    self.report("error", "failed", f"{self.device_name} stopped recording: {exc}")
                    return
            except MirrorlabError as exc:  # damaged data, a device error: retrying cannot help
                self.failed = exc
                self.report("error", "failed", f"{self.device_name} stopped recording: {exc}")
                return
            except Exception as exc:  # a driver bug: report it, keep the session alive
                self.failed = exc
                self.report("error", "failed", f"{self.device_name} acquisition failed: "
                                               f"{type(exc).__name__}: {exc}")
                return

    def _reconnect_with_backoff(self) -> bool:
        delay = 0.05
        while not self._stop.is_set():
            if self._stop.wait(delay):
                return False
            try:
                self.reconnect()
            except (DeviceError, OSError) as exc:
                self.report("info", "reconnect_retry", f"{self.device_name}: reconnect failed ({exc}); "
                                                       f"retrying in {min(delay * 2, self.max_backoff):g} s")
                delay = min(delay * 2, self.max_backoff)
                continue
            self.reconnects += 1
            self.report("info", "reconnected", f"{self.device_name} reconnected", reconnects=self.reconnects)
            return True
        return False


class SerialInstrument(Instrument):
    """An instrument that speaks the mirrorlab line protocol (``instruments.md`` §0.2).

    Provides connect / identify / status / close and :meth:`query`; subclasses implement
    :meth:`apply_settings`, :meth:`streams`, :meth:`acquire` and :meth:`read`.
    """

    #: The ``kind`` field ``*IDN?`` must answer (``FSCAN``, ``USDF``...).
    kind: ClassVar[str]
    baudrate: ClassVar[int] = 115200

    def __init__(self, label: str, port: str | None = None, settings: Mapping[str, Any] | None = None,
                 timeout: float = 2.0, report: Reporter | None = None) -> None:
        super().__init__(label, port, settings, timeout, report)
        self.client: LineClient | None = None

    @classmethod
    def needs_port(cls, settings: Mapping[str, Any]) -> bool:
        return True

    def on_unsolicited(self, line: str) -> None:
        """Handle a ``!`` line (reader thread). ``!ERR`` is reported; subclasses add stream lines."""
        if line.startswith("ERR"):
            self.report("warning", "device_fault", f"{self.device_name} reports {line}")

    def connect(self) -> None:
        if self.client is not None and self.client.alive:
            return
        if not self.port:
            raise DeviceDisconnected(f"{self.name} {self.label!r}: no port given; set `port` to the "
                                     "device path or URL (or `simulate = true` in a recipe)")
        port = open_port(self.port, self.baudrate)
        self.client = LineClient(port, self.device_name, self.timeout, self.on_unsolicited)
        try:
            reply = self.query("PING")
            if reply.fields != ["PONG"]:  # a reply left over from before a replug, not ours
                raise ProtocolError(f"{self.device_name} answered PING with {' '.join(reply.fields)!r}: a "
                                    "stale reply from before the connection; connect again")
        except DeviceError:
            self.close()
            raise

    def query(self, command: str, timeout: float | None = None) -> Reply:
        """Send one command and return its reply (see :meth:`LineClient.query`)."""
        if self.client is None:
            raise DeviceDisconnected(f"{self.device_name} is not connected; call connect() first")
        return self.client.query(command, timeout)

    def identify(self) -> Identity:
        reply = self.query("*IDN?")
        if len(reply.fields) != 5:
            raise ProtocolError(f"{self.device_name}: *IDN? gave {' '.join(reply.fields)!r}, "
                                "expected '<kind> <vendor> <model> <firmware> <serial>'")
        if reply.fields[0] != self.kind:
            raise ProtocolError(f"{self.device_name}: the device is a {reply.fields[0]}, not a {self.kind}; "
                                "check that the port is the right device")
        self.identity = Identity(*reply.fields)
        return self.identity

    def status(self) -> Status:
        reply = self.query("STAT?")
        flags = reply.field(1, "flags")
        return Status(reply.field(0, "state"), tuple(f for f in flags.split(",") if f != "-"), True,
                      {"reconnects": self.reconnects,
                       "garbage_lines": self.client.garbage_lines if self.client else 0})

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None

    def simulate_query(self, command: str) -> Reply:
        """Send a ``SIM:`` command (only a simulator accepts it)."""
        if not command.upper().startswith("SIM:"):
            raise ValueError("simulate_query sends SIM: commands only")
        return self.query(command)

    def wait_until(self, predicate: Callable[[], bool], timeout: float, what: str) -> None:
        """Poll ``predicate`` until true or raise :class:`DeviceTimeout` naming ``what``."""
        deadline = time.monotonic() + timeout
        while not predicate():
            if time.monotonic() > deadline:
                raise DeviceTimeout(f"{self.device_name}: {what} did not happen within {timeout:g} s")
            time.sleep(0.01)
