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
and ``status`` may be called any time after ``connect``; :meth:`set` changes one live parameter
(a set-point) at any time, returning a :class:`~mirrorlab.core.devices.SetStatus` at once. Every
call is bounded by ``timeout``.

While started, :meth:`acquire` runs in the instrument's own thread and the instrument's
:attr:`~Instrument.state` says what it is doing (:class:`InstrumentState`). Errors decide their own fate:

* *transient* (:class:`DeviceDisconnected`, :class:`DeviceTimeout`, :class:`ProtocolError`): the
  base class reports it, reconnects with exponential backoff within the reconnect budget
  (:attr:`~Instrument.reconnect_budget`, s) and resumes — other instruments keep acquiring;
* *permanent* (any other :class:`MirrorlabError`: damaged data :class:`DataError`, a setting that
  cannot work :class:`ConfigurationError`, a device's ``ERR`` reply): the instrument stops,
  reported once, and is ``failed``.
"""

from __future__ import annotations

import threading
import time
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, ClassVar, Literal

import numpy as np

from ..errors import (
    ConfigurationError,
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
from .setpoint import SetStatus
from .simulator import LineSimulator, SimulatedWorld
from .transport import open_port


class InstrumentState(StrEnum):
    """Lifecycle state of an instrument (:attr:`Instrument.state`).

    A ``str``: a state compares equal to its value (``state == "acquiring"``) and is stored and
    printed as it (event data, JSON, the console), so the values are part of the session file format.
    """

    IDLE = "idle"                  #: connected (or not yet), not acquiring
    CONNECTING = "connecting"      #: opening the connection
    ACQUIRING = "acquiring"        #: its acquisition thread runs
    RECONNECTING = "reconnecting"  #: lost the device while acquiring, reconnecting within the budget
    FAILED = "failed"              #: stopped by a permanent error (:attr:`Instrument.failed`)
    STOPPED = "stopped"            #: acquisition ended (told to, the source ended, or disconnected)


#: The value of each lifecycle state, for callers that name one by its string (``set_state("idle")``);
#: a test checks that it lists exactly the values of :class:`InstrumentState`.
StateName = Literal["idle", "connecting", "acquiring", "reconnecting", "failed", "stopped"]
#: Lifecycle states of an instrument, as their values.
STATES: tuple[str, ...] = tuple(s.value for s in InstrumentState)
#: Errors after which reconnecting may help.
TRANSIENT = (DeviceDisconnected, DeviceTimeout, ProtocolError)

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
    #: The keys of a session's shared simulated world (a recipe's ``[world]`` table) this plugin's
    #: simulator understands; ``None``: its simulator has a world of its own. A session with a world
    #: hands it to :meth:`make_simulator` of these plugins only.
    world_parameters: ClassVar[ParameterSet | None] = None
    supports_reconnect: ClassVar[bool] = True
    max_backoff: ClassVar[float] = 5.0
    #: Seconds the acquisition thread may take to end after :meth:`stop` (after ``ABORT``).
    stop_timeout: ClassVar[float] = 1.0
    #: Seconds between the acquisition thread's refreshes of :attr:`last_status`.
    status_interval: ClassVar[float] = 1.0

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
        #: Seconds of reconnect attempts allowed per connection loss; ``None``: no limit.
        self.reconnect_budget: float | None = 60.0
        #: :func:`time.monotonic` at which the running reconnect attempts give up (``None``: none running).
        self.reconnect_deadline: float | None = None
        #: The newest :class:`Status`, cached by the acquisition thread (never a device call to read).
        self.last_status: Status | None = None
        self.state: InstrumentState = InstrumentState.IDLE
        self._status_due = 0.0
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        # sends the set-points, one at a time in the order given, whichever thread gives them; made on
        # the first set() (most instruments have no set-point); its idle thread ends with the instrument
        self._setpoints: ThreadPoolExecutor | None = None
        self._setpoints_lock = threading.Lock()

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
    def make_simulator(cls, settings: Mapping[str, Any], seed: int, world: SimulatedWorld | None = None) -> LineSimulator:
        """The device model a simulated instance with these ``settings`` talks to.

        Called by :meth:`mirrorlab.core.Session.add_instrument` (``simulate=True``), recipes
        (``simulate = true``) and the conformance kit; the session serves the model on a pty or
        TCP socket and the driver talks to it like to the real device. ``seed`` makes its noise
        reproducible. The default builds :attr:`simulator` (``cls.simulator(seed=seed)``);
        override it when the model depends on the settings (the film scanner films the scene
        or images its settings name), or to put the model in the session's shared ``world``
        (given only to plugins that declare :attr:`world_parameters`; the default ignores it).

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
        overridden = any("make_simulator" in vars(c) for c in cls.__mro__[:cls.__mro__.index(Instrument)])
        return cls.simulator is not None or overridden

    def configure(self, **changes: Any) -> dict[str, Any]:
        """Validate ``changes`` against :attr:`parameters`, apply them, return all settings."""
        merged = {**self.settings, **changes}
        self.settings = self.parameters.validate(merged, where=f"instruments.{self.label}.settings")
        self.apply_settings(self.settings)
        return dict(self.settings)

    def set(self, name: str, value: Any, timeout: float | None = None) -> SetStatus:
        """Send one live-settable parameter (a set-point); return at once, with its :class:`SetStatus`.

        Only ``name`` is validated (against its declaration and the other current settings), now, in
        the calling thread; the instrument's set-point thread then sends it, and nothing else, to the
        device. Set-points are sent one at a time, in the order given, whichever thread gives them;
        safe to call from any thread, also while acquiring. ``set(...).wait()`` returns when the
        device acknowledged it, with the applied value, or raises the device's error.

        Parameters
        ----------
        name
            One of the instrument's set-points: a parameter declared with ``live=True``
            (:attr:`ParameterSet.setpoints <mirrorlab.core.params.ParameterSet.setpoints>`).
        value
            New value, in the parameter's unit (or a ``"<number> <unit>"`` string).
        timeout
            Seconds the device has to acknowledge it once sent (default: the instrument's ``timeout``);
            past it the status fails with :class:`DeviceTimeout`.

        Raises
        ------
        ValidationError
            ``name`` is not a set-point of this instrument, or ``value`` is not valid for it.
        """
        setpoints = self.parameters.setpoints
        if name not in setpoints:
            problem = (f"{self.name} has no parameter {name!r}" if name not in self.parameters else
                       f"not live-settable; change it with configure() (live-settable: {', '.join(setpoints) or 'none'})")
            raise ValidationError([Problem(f"instruments.{self.label}.{name}", problem)])
        settings = self.parameters.validate({**self.settings, name: value},
                                            where=f"instruments.{self.label}.settings")
        status = SetStatus(self.device_name, name, settings[name])
        with self._setpoints_lock:
            if self._setpoints is None:
                self._setpoints = ThreadPoolExecutor(1, thread_name_prefix=f"set-points {self.label}")
            self._setpoints.submit(self._send_setpoint, status, self.timeout if timeout is None else timeout)
        return status

    def _send_setpoint(self, status: SetStatus, timeout: float) -> None:
        """In the set-point thread: send one validated set-point, then finish its status."""
        error: Exception | None = None
        try:
            self.apply_setpoint(status.name, status.value, timeout)
            self.settings[status.name] = status.value
        except Exception as exc:  # the status carries it to whoever waits (a controller reports it)
            error = exc
        for failed in status.finish(error):
            self.report("error", "setpoint_callback_failed", f"{self.device_name}: a callback of the set-point "
                        f"{status.name} raised {type(failed).__name__}: {failed}")

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

    def set_state(self, state: InstrumentState | StateName, message: str = "") -> None:
        """Enter lifecycle ``state`` and report the change as a ``state`` event."""
        if state not in STATES:
            raise ValueError(f"state must be one of {STATES}, not {state!r}")
        state = InstrumentState(state)
        if state != self.state:
            self.state = state
            # info: the cause (connection_lost, failed...) is its own event at its own level
            self.report("info", "state", message or f"{self.device_name} is {state}", state=state.value)

    def start(self, emit: Emit) -> None:
        """Start :meth:`acquire` in the instrument's thread (reconnecting on connection loss)."""
        if self._thread is not None and self._thread.is_alive():
            raise DeviceError(f"{self.device_name} is already started; stop it first")
        self._stop.clear()
        self.failed = None
        self._thread = threading.Thread(target=self._run, args=(_StatusCaching(emit, self),),
                                        name=f"acquire {self.label}", daemon=True)
        self.set_state(InstrumentState.ACQUIRING)
        self._thread.start()

    def stop(self, timeout: float | None = None) -> None:
        """Stop acquiring: interrupt a running device command, wait for the thread (idempotent).

        The thread must end within ``timeout`` (default :attr:`stop_timeout`) s; otherwise the
        instrument is reported ``failed`` (its device did not obey the interrupt).
        """
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread() and thread.is_alive():
            try:
                self.interrupt()
            except (DeviceError, OSError) as exc:  # the device is gone anyway: the thread ends on its own
                self.report("debug", "interrupt_failed", f"{self.device_name}: {exc}")
            thread.join(timeout=self.stop_timeout if timeout is None else timeout)
            if thread.is_alive():
                self.failed = DeviceTimeout(f"{self.device_name}: acquisition did not stop within "
                                            f"{self.stop_timeout:g} s of being told to")
                self.report("error", "stop_timeout", f"{self.failed}; power-cycle the device before using it again")
                self.set_state(InstrumentState.FAILED)
                return
        self._thread = None
        if self.state in (InstrumentState.ACQUIRING, InstrumentState.RECONNECTING):
            self.set_state(InstrumentState.STOPPED)

    def interrupt(self) -> None:
        """Make a running device command end now (called by :meth:`stop`); default: nothing to interrupt."""
        return None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def reconnect(self) -> None:
        """Close, connect, identify and re-apply settings."""
        self.close()
        self.connect()
        self.identify()
        self.apply_settings(self.settings)

    def refresh_status(self) -> Status | None:
        """Ask the device for its :meth:`status` and cache it in :attr:`last_status` (``None`` if it fails)."""
        try:
            self.last_status = self.status()
        except (MirrorlabError, OSError):
            return None
        return self.last_status

    def _tick(self) -> None:
        """After each emitted block, in the acquisition thread: refresh the cached status now and then."""
        now = time.monotonic()
        if now >= self._status_due and threading.current_thread() is self._thread:
            self._status_due = now + self.status_interval
            self.refresh_status()

    def _run(self, emit: Emit) -> None:
        while not self._stop.is_set():
            try:
                self.acquire(emit, self._stop)
                if not self._stop.is_set():
                    self.set_state(InstrumentState.STOPPED, f"{self.device_name}: the source has ended")
                return
            except TRANSIENT as exc:
                if self._stop.is_set():
                    return
                self.report("warning", "connection_lost", f"{self.device_name}: {exc}")
                if not self.supports_reconnect or not self._reconnect_with_backoff():
                    self._fail(exc, "stopped acquiring")
                    return
            except Exception as exc:  # permanent: damaged data, a device's ERR, a setting, a driver bug
                if self._stop.is_set():  # e.g. the command aborted by stop()
                    return
                what = "stopped acquiring" if isinstance(exc, MirrorlabError) else \
                    f"acquisition failed ({type(exc).__name__})"
                self._fail(exc, what)
                return

    def _fail(self, exc: BaseException, what: str) -> None:
        self.failed = exc
        self.report("error", "failed", f"{self.device_name} {what}: {exc}")
        self.set_state(InstrumentState.FAILED)

    def _reconnect_with_backoff(self) -> bool:
        """Reconnect within :attr:`reconnect_budget`; ``False`` if stopped, out of budget or permanent."""
        self.set_state(InstrumentState.RECONNECTING)
        budget = self.reconnect_budget
        self.reconnect_deadline = None if budget is None else time.monotonic() + budget
        delay = 0.05
        try:
            while not self._stop.is_set():
                left = None if self.reconnect_deadline is None else self.reconnect_deadline - time.monotonic()
                if left is not None and left <= 0:
                    self.report("error", "reconnect_budget", f"{self.device_name} did not come back within "
                                f"{budget:g} s; check cable and power, then start acquiring again")
                    return False
                if self._stop.wait(delay if left is None else min(delay, left)):
                    return False
                try:
                    self.reconnect()
                except TRANSIENT + (OSError,) as exc:
                    delay = min(delay * 2, self.max_backoff)
                    self.report("info", "reconnect_retry", f"{self.device_name}: reconnect failed ({exc}); "
                                                           f"retrying in {delay:g} s")
                    continue
                except MirrorlabError as exc:  # e.g. another kind of device on the port now
                    self.report("error", "reconnect_refused", f"{self.device_name}: {exc}")
                    return False
                self.reconnects += 1
                self.report("info", "reconnected", f"{self.device_name} reconnected", reconnects=self.reconnects)
                self.set_state(InstrumentState.ACQUIRING)
                return True
            return False
        finally:
            self.reconnect_deadline = None


class _StatusCaching:
    """The ``emit`` an acquisition thread gets: publish, then let the instrument refresh its cached status."""

    def __init__(self, emit: Emit, instrument: Instrument) -> None:
        self._emit = emit
        self._tick = instrument._tick
        self.now: Callable[[], float] = getattr(emit, "now", time.monotonic)

    def __call__(self, stream: str, times: Any, values: Any) -> None:
        self._emit(stream, times, values)
        self._tick()


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
        """Handle a ``!`` line (reader thread). ``!ERR`` is reported, and so is ``!OVF <n>`` (the device dropped
        ``n`` stream lines: the host read too slowly, or the line cannot carry the stream); subclasses add
        stream lines."""
        if line.startswith("ERR"):
            self.report("warning", "device_fault", f"{self.device_name} reports {line}")
        elif line.startswith("OVF "):
            self.report("warning", "device_overflow", f"{self.device_name} dropped {line[4:]} stream lines: they "
                        "were read too slowly, or the serial line is too slow for the stream (lower its rate)")

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

    def interrupt(self) -> None:
        """Send ``ABORT`` to the command the acquisition thread is waiting on, if any."""
        client = self.client
        if client is not None and client.busy:
            client.abort()

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
            raise ConfigurationError(f"{self.device_name}: the device is a {reply.fields[0]}, not a {self.kind}; "
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
