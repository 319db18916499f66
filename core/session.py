"""The session: one experiment, one HDF5 file.

Create a session, add instruments (real or simulated), record, run algorithms, read results::

    >>> import tempfile, pathlib
    >>> from mirrorlab.core import Session
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "demo.h5"
    >>> with Session.create(path, operator="ana", description="doc example") as s:
    ...     cam = s.add_instrument("cam", "film_scanner", simulate=True,
    ...                            settings={"lines": 32}, simulator={"clock": "FAST"})
    ...     stats = s.record(seconds=0.5)
    >>> stats["cam/frames"]["dropped"]
    0
    >>> with Session.open(path) as s:
    ...     times, frames = s.stream("cam", "frames")
    ...     s.status, frames.shape[1:]
    ('closed', (32, 512))

Files are opened read-only unless ``writable=True`` (or created). Recording switches the file to
SWMR mode, so another process may read it while it grows; results are written after recording,
each algorithm run into a new ``/results/<algorithm>/<run-id>`` group that is never overwritten.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import platform
import re
import socket
import sys
import threading
import time
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import h5py
import numpy as np

from .algorithms import Algorithm, AlgorithmExecutor, ResultRef, RunContext, execute, label_problem
from .clock import SessionClock, parse_utc, utc_now_iso
from .controller_runtime import ControllerRunner
from .controllers import Controller
from .devices import Instrument, SerialInstrument, SimulatedWorld, SimulatorServer
from .digests import read_hashed
from .errors import Problem, SessionError, SessionExistsError, ValidationError
from .events import EventBus
from .params import Parameter, ParameterSet, to_jsonable
from .registry import Registry, get_registry
from .snapshot import ControllerSnapshot, InstrumentSnapshot, RecorderSnapshot, SessionSnapshot
from .store import files, schema
from .store.recorder import Recorder
from .store.schema import LIBVER
from .streams import Emitter, StreamRouter, Subscription
from .version import distribution_version as _version
from .version import mirrorlab_version

SIMULATOR_OPTIONS = ParameterSet(
    Parameter("seed", int, 0, bounds=(0, None), help="seed of the simulator's random generator"),
    Parameter("clock", str, "REAL", choices=("REAL", "FAST"),
              help="REAL: modelled timing in real time; FAST: as fast as possible"),
    Parameter("transport", str, "pty", choices=("pty", "tcp"), help="byte stream the driver talks through"),
)

_PACKAGES = ("numpy", "scipy", "h5py", "pluggy", "pyserial", "opencv-python-headless", "textual", "rich")


def _unit(declared: str, units: Mapping[str, str]) -> str:
    """A declared output unit with each ``{input}`` replaced by that input's unit when it is known.

    >>> _unit("{values}/s", {"values": "mm"}), _unit("{values}/s", {})
    ('mm/s', '{values}/s')
    """
    return re.sub(r"\{(\w+)\}", lambda m: units.get(m[1]) or m[0], declared)


def _dataset_unit(dataset: h5py.Dataset) -> str:
    """The unit of a dataset: its own ``unit``, else its stream group's (``time_unit`` for ``time``)."""
    own = schema.attr_str(dataset, "unit")
    if own or "unit" not in dataset.parent.attrs:
        return own
    return schema.attr_str(dataset.parent, "time_unit" if dataset.name.endswith("/time") else "unit")


@dataclass
class StreamData:
    """A recorded stream: ``times`` (n,) s, ``data`` (n, *shape), and its attributes."""

    times: np.ndarray
    data: np.ndarray
    unit: str
    attrs: dict[str, Any]

    def __iter__(self):  # allows ``times, data = session.stream(...)``
        return iter((self.times, self.data))


@dataclass
class ResultData:
    """A stored algorithm run: its outputs and provenance attributes."""

    ref: ResultRef
    outputs: dict[str, np.ndarray]
    attrs: dict[str, Any]


class Session:
    """One session file. Use :meth:`create` or :meth:`open`, as context managers."""

    def __init__(self, path: Path, file: h5py.File, writable: bool, registry: Registry,
                 crashed: bool = False) -> None:
        self.path = path
        self.file = file
        self.writable = writable
        self.crashed = crashed
        self.registry = registry
        origin = schema.attr_str(file, "clock_origin_utc")
        # Schema 1 files have no stored origin: each opening restarts at 0, as it did then.
        self.clock = SessionClock(parse_utc(origin) if origin else None)
        #: Set by request_stop(): algorithm runs (and record) end cooperatively at their next check.
        self._cancel = threading.Event()
        self.events = EventBus(self.clock)
        self.router = StreamRouter(on_overflow=self._on_overflow)
        self.instruments: dict[str, Instrument] = {}
        self.controllers: dict[str, ControllerRunner] = {}
        self._simulators: dict[str, SimulatorServer] = {}
        #: The simulated world this session's simulators share (:meth:`set_world`); ``None``: each its own.
        self.world: SimulatedWorld | None = None
        # One lock for every change of state (instruments, acquisition, recording, closing), so a UI
        # thread and a script thread never race; snapshot() takes none.
        self._lock = threading.RLock()
        self._operations = 0
        self._shared = 0  # depth of shared_for_reading()
        self._acquiring: set[str] = set()
        self._recorder: Recorder | None = None
        self._last_recorder: Recorder | None = None
        self._recording: list[str] = []
        self._recorded_controllers: list[str] = []
        self._reconnects_at_start: dict[str, int] = {}
        self._recorded_streams: list[tuple[str, str]] = []
        self._closed = False
        self._created = False
        self._draft: Path | None = None  # the file as created, until _commit (see create)
        #: How long the last recording lasted (start to stop of the instruments), s.
        self.recorded_seconds = 0.0
        self._record_start = 0.0
        #: Runs algorithms for :meth:`run` instead of this process (see :mod:`mirrorlab.core.batch`):
        #: called as ``executor(session, cls, inputs, params, context)`` with inputs as h5py datasets
        #: or arrays, returns the ``RunOutcome`` and each input's digest entry
        #: (:func:`~mirrorlab.core.digests.input_entry`); its ``provenance`` dict is stored as ``@executor``.
        self.executor: AlgorithmExecutor | None = None
        for message in registry.notify("mirrorlab_session_opened", session=self):
            self.events.emit("warning", "session", "plugin_error", message)

    # -- opening ---------------------------------------------------------------------------------
    @classmethod
    def create(cls, path: str | Path, *, operator: str = "", description: str = "",
               recipe: Mapping[str, Any] | None = None, registry: Registry | None = None,
               overwrite: bool = False) -> Session:
        """Create a new session file (status ``open``).

        Parameters
        ----------
        path
            File to create; its folder is created if needed.
        operator, description
            Who runs it and what it is, stored as root attributes.
        recipe
            ``{"text": ..., "overrides": [...], "effective": {...}, "path": ...}`` of the recipe
            as run (see :mod:`mirrorlab.core.recipes`); stored under ``/config``.
        overwrite
            Replace an existing file instead of refusing (:class:`SessionExistsError`).

        The new file is a *draft* until it holds something: until recording starts, a group or a
        result is written, or the session is closed cleanly. A draft closed as ``aborted`` (an
        exception escaped the ``with`` block, e.g. an instrument that would not connect) is deleted,
        so a failed start leaves no file behind; with ``overwrite`` the draft is written beside the
        old file and replaces it only then, so a failed start keeps the old file as it was.
        """
        path = Path(path)
        if path.exists() and not overwrite:
            raise SessionExistsError(path)
        if path.is_dir():
            raise SessionError(f"{path} is a folder; give a file name such as {path / 'session.h5'}")
        registry = registry or get_registry()
        # The new file is a draft until it holds something (see _commit): written beside an existing
        # file, so that a start that fails neither leaves a file behind nor destroys the old one.
        draft = path.with_name(f".{path.name}.{uuid.uuid4().hex[:8]}.draft") if path.exists() else path
        try:
            f = files.open_writable(draft, "w-")
        except FileExistsError:
            raise SessionExistsError(path) from None
        try:
            created = utc_now_iso()
            f.attrs.update({
                "mirrorlab_schema": schema.SCHEMA_VERSION,
                "mirrorlab_version": mirrorlab_version(),
                "session_id": str(uuid.uuid4()),
                "created_utc": created,
                "clock_origin_utc": created,  # session time 0 of /log, streams and controllers
                "operator": operator,
                "description": description,
                "status": "open",
            })
            for name in schema.GROUPS:
                f.create_group(name)
            schema.create_log(f)
            cls._write_config(f, recipe or {}, registry)
            f.flush()
        except BaseException:
            f.close()
            draft.unlink(missing_ok=True)
            raise
        session = cls(path, f, True, registry)
        session._created = True
        session._draft = draft
        return session

    @classmethod
    def open(cls, path: str | Path, writable: bool = False, registry: Registry | None = None) -> Session:
        """Open an existing session, read-only unless ``writable``.

        A file left open by a crash opens read-only (SWMR) with ``crashed = True``; to write to it,
        first run ``mirrorlab session close FILE --aborted``.
        """
        path = Path(path)
        registry = registry or get_registry()
        f, crashed = files.open_readonly(path)
        try:
            with files.reading(path):
                is_session = "mirrorlab_schema" in f.attrs
        except SessionError:
            f.close()
            raise
        if not is_session:
            f.close()
            raise SessionError(f"{path} is an HDF5 file but not a mirrorlab session (no mirrorlab_schema)")
        if writable:
            f.close()
            if crashed:
                raise SessionError(f"{path} was left open by a recording that did not finish; run "
                                   f"`mirrorlab session close {path} --aborted` before writing to it")
            f = files.open_writable(path)
        return cls(path, f, writable, registry, crashed)

    @staticmethod
    def _write_config(f: h5py.File, recipe: Mapping[str, Any], registry: Registry) -> None:
        config = f["config"]
        text = recipe.get("text", "")
        config.create_dataset("recipe", data=text, dtype=schema.STR)
        config.attrs["recipe_path"] = str(recipe.get("path", ""))
        config.attrs["recipe_hash"] = "sha256:" + hashlib.sha256(
            (text + json.dumps(recipe.get("overrides", []))).encode()).hexdigest()
        schema.set_json(config, "overrides", list(recipe.get("overrides", [])))
        schema.set_json(config, "recipe_effective", recipe.get("effective", {}))
        provenance = {
            "python": sys.version,
            "platform": platform.platform(),
            "host": socket.gethostname(),
            "hdf5": h5py.version.hdf5_version,
            "packages": {p: _version(p) for p in _PACKAGES},
            "mirrorlab": mirrorlab_version(),
            # every installed plugin; one not imported yet (see Registry) is listed with what it declares
            "plugins": {name: {"source": p.source, "distribution": p.distribution, "version": p.version,
                               "ok": p.ok, "provides": p.provides if p.loaded else p.declared}
                        for name, p in registry.installed().items()},
        }
        config.create_dataset("provenance", data=json.dumps(provenance, indent=1, sort_keys=True),
                              dtype=schema.STR)

    # -- basic properties ------------------------------------------------------------------------
    def __enter__(self) -> Session:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        # An exception while *recording* a new session aborts it; analysis of an existing
        # session keeps that session's status whatever happens.
        self.close("aborted" if exc_type is not None and self._created else None)

    @property
    def status(self) -> str:
        return schema.attr_str(self.file, "status")

    @property
    def session_id(self) -> str:
        return schema.attr_str(self.file, "session_id")

    @property
    def attrs(self) -> dict[str, Any]:
        return {k: (schema.text(v) if isinstance(v, (bytes, str)) else v.item() if hasattr(v, "item") else v)
                for k, v in self.file.attrs.items()}

    def _require_writable(self, what: str) -> None:
        if not self.writable:
            raise SessionError(f"{self.path} is open read-only; open it with writable=True to {what}")
        if self._recorder is not None and what != "record":
            raise SessionError(f"cannot {what} while recording (the file's layout is fixed); stop first")

    def _commit(self) -> None:
        """The new file now holds something worth keeping: put it at its path (see :meth:`create`)."""
        if self._draft is not None and self._draft != self.path:
            os.replace(self._draft, self.path)  # the open HDF5 file follows its inode
        self._draft = None

    # -- instruments -----------------------------------------------------------------------------
    def add_instrument(self, label: str, plugin: str, *, port: str | None = None,
                       settings: Mapping[str, Any] | None = None, simulate: bool = False,
                       simulator: Mapping[str, Any] | None = None, timeout: float = 2.0,
                       reconnect: float | None = 60.0) -> Instrument:
        """Create, connect, identify and configure an instrument and describe it in the file.

        Parameters
        ----------
        label
            Its name in this session (HDF5 group ``/instruments/<label>``).
        plugin
            Registered instrument name (``mirrorlab plugins`` lists them).
        port
            Device path or pyserial URL; ignored when ``simulate``.
        settings
            Instrument settings, validated against the plugin's parameters.
        simulate
            Start the plugin's simulator on a pseudo-terminal (or TCP) and drive it through the
            real driver.
        simulator
            Simulator options: ``seed``, ``clock`` (``REAL``/``FAST``), ``transport`` (``pty``/``tcp``).
        timeout
            Seconds allowed for each device call.
        reconnect
            Reconnect budget: seconds of attempts after a lost connection before the instrument is
            ``failed`` (``None``: keep trying; 0: never reconnect).
        """
        with self._lock:
            return self._add_instrument(label, plugin, port, settings, simulate, simulator, timeout, reconnect)

    def _add_instrument(self, label: str, plugin: str, port: str | None, settings: Mapping[str, Any] | None,
                        simulate: bool, simulator: Mapping[str, Any] | None, timeout: float,
                        reconnect: float | None) -> Instrument:
        self._require_writable("add an instrument")
        if label in self.instruments or f"instruments/{label}" in self.file:
            raise SessionError(f"an instrument labelled {label!r} is already in this session; pick another label")
        cls = self.registry.instrument(plugin)
        sim_options = SIMULATOR_OPTIONS.validate(dict(simulator or {}), where=f"instruments.{label}.simulator")
        instrument: Instrument = cls(label, port, settings, timeout, report=self._reporter(label))
        instrument.reconnect_budget = reconnect
        # Only a device on a port has a simulator to serve; other sources (files, a virtual
        # scene) are their own simulation.
        served = simulate and cls.needs_port(instrument.settings)
        if served:
            server = self._start_simulator(cls, instrument.settings, sim_options, label)
            instrument.port = server.url
        instrument.set_state("connecting")
        try:
            instrument.connect()
            instrument.identify()
            if served and isinstance(instrument, SerialInstrument):
                instrument.simulate_query(f"SIM:SEED {sim_options['seed']}")
                instrument.simulate_query(f"SIM:CLOCK {sim_options['clock']}")
            instrument.configure()
            instrument.refresh_status()
        except BaseException:
            instrument.close()
            self._stop_simulator(label)
            raise
        instrument.set_state("idle")
        self.instruments[label] = instrument
        g = self.file["instruments"].create_group(label)
        meta = instrument.metadata()
        g.attrs["plugin"] = meta["plugin"]
        g.attrs["version"] = meta["version"]
        g.attrs["port"] = meta["port"]
        g.attrs["simulated"] = bool(simulate)
        schema.set_json(g, "settings", to_jsonable(instrument.settings))
        schema.set_json(g, "identity", meta["identity"])
        g.attrs["firmware"] = meta["identity"].get("firmware", "")
        if served:
            schema.set_json(g, "simulator", sim_options)
        self.events.emit("info", label, "instrument_added",
                         f"{plugin} {label!r} ready" + (" (simulated)" if simulate else
                                                         f" on {instrument.port}" if instrument.port else ""))
        return instrument

    def set_world(self, settings: Mapping[str, Any]) -> SimulatedWorld:
        """Give this session one simulated world, shared by the simulators added after this call.

        ``settings`` are the world's keys (a recipe's ``[world]`` table), checked by the first
        simulator that builds the world against its plugin's ``world_parameters`` (e.g. the
        trackers': ``mirrorlab.instruments.virtual_lab.worlds``). The world runs on the session
        clock, so its ground truth and the recorded streams share one time axis.

        Raises
        ------
        SessionError
            A simulator is already running: it would not see the world.
        """
        with self._lock:
            self._require_writable("set the simulated world")
            if self._simulators:
                raise SessionError(f"set the simulated world before adding simulated instruments "
                                   f"({', '.join(self._simulators)} already run without it)")
            self.world = SimulatedWorld(settings, self.clock.now)
            return self.world

    def _start_simulator(self, cls: type[Instrument], settings: dict[str, Any], options: dict[str, Any],
                         label: str) -> SimulatorServer:
        if self.world is not None and cls.world_parameters is not None:
            model = cls.make_simulator(settings, options["seed"], world=self.world)
        else:
            model = cls.make_simulator(settings, options["seed"])
        server = SimulatorServer(model, options["transport"]).start()
        self._simulators[label] = server
        return server

    def _stop_simulator(self, label: str) -> None:
        server = self._simulators.pop(label, None)
        if server is not None:
            server.close()

    def simulator(self, label: str) -> SimulatorServer:
        """The simulator serving instrument ``label`` (for fault injection in tests and demos)."""
        try:
            return self._simulators[label]
        except KeyError:
            raise SessionError(f"instrument {label!r} is not simulated in this session") from None

    def _reporter(self, label: str) -> Callable[..., None]:
        def report(level: str, kind: str, message: str, **data: Any) -> None:
            self.events.emit(level, label, kind, message, **data)
        return report

    def _on_overflow(self, block: Any, dropped: int) -> None:
        self.events.emit("warning", block.instrument, "overflow",
                         f"recorder queue full: {dropped} samples of {block.instrument}/{block.stream} "
                         "dropped so far (the disk or the recorder cannot keep up)", dropped=dropped)

    def subscribe(self, source: str, stream: str, max_bytes: int = 64 << 20) -> Subscription:
        """Live view of a stream of an instrument or controller, independent of the file.

        The subscription holds at most ``max_bytes`` of unread blocks (oldest dropped first) and is
        released by its ``close()``, its ``with`` block or the session's close.
        """
        return self.router.subscribe([(source, stream)], max_bytes)

    # -- controllers -----------------------------------------------------------------------------
    def add_controller(self, label: str, plugin: str | type[Controller], *,
                       settings: Mapping[str, Any] | None = None, inputs: Mapping[str, str] | None = None,
                       instruments: Mapping[str, str] | None = None) -> ControllerRunner:
        """Add a controller bound to streams and instruments of this session.

        Parameters
        ----------
        label
            Its name in this session (HDF5 group ``/controllers/<label>``).
        plugin
            Registered controller name (``mirrorlab plugins`` lists them) or class.
        settings
            Controller settings, validated against its parameters.
        inputs
            Input role -> ``"<instrument>/<stream>"`` it subscribes to.
        instruments
            Commanded role -> instrument label; the parameters it sets must be live-settable.

        It starts with acquisition, after its instruments, and stops before them; while recording,
        its set-points, their latencies and its streams are recorded under ``/controllers/<label>``.
        """
        with self._lock:
            self._require_writable("add a controller")
            if label in self.controllers or label in self.instruments:
                raise SessionError(f"{label!r} already names an instrument or controller of this session; "
                                   "pick another label")
            cls = self.registry.controller(plugin) if isinstance(plugin, str) else plugin
            controller = cls(label, settings)
            where = f"controllers.{label}"
            bound_inputs, bound_instruments, problems = self._bind(controller, where, dict(inputs or {}),
                                                                   dict(instruments or {}))
            if problems:
                raise ValidationError(problems)
            runner = ControllerRunner(controller, bound_inputs, bound_instruments, Emitter(label, self.router, self.clock),
                                      self.router.subscribe, self._reporter(label))
            runner.emitter.streams = {s.name: s for s in runner.streams()}
            self._commit()
            g = self.file.require_group("controllers").create_group(label)
            g.attrs.update({"plugin": cls.name, "version": cls.version, "description": cls.description})
            schema.set_json(g, "settings", to_jsonable(controller.settings))
            schema.set_json(g, "inputs", dict(inputs or {}))
            schema.set_json(g, "instruments", dict(instruments or {}))
            self.file.flush()
            self.controllers[label] = runner
            self.events.emit("info", label, "controller_added", f"controller {cls.name} {label!r} ready")
            if self._acquiring:
                self._start_controllers()
            return runner

    def _bind(self, controller: Controller, where: str, inputs: dict[str, str], instruments: dict[str, str]
              ) -> tuple[dict[str, tuple[str, str]], dict[str, Instrument], list[Problem]]:
        """Check a controller's bindings against its declared roles and this session's instruments."""
        cls = type(controller)
        commanded = controller.commanded()
        problems: list[Problem] = []
        bound_inputs: dict[str, tuple[str, str]] = {}
        bound_instruments: dict[str, Instrument] = {}
        for role in set(inputs) - set(cls.inputs):
            problems.append(Problem(f"{where}.inputs.{role}", f"{cls.name} has no input {role!r}; "
                                    f"its inputs: {', '.join(cls.inputs) or 'none'}"))
        for role, what in cls.inputs.items():
            ref = inputs.get(role)
            if ref is None:
                problems.append(Problem(f"{where}.inputs.{role}", f"required: \"<instrument>/<stream>\" ({what})"))
                continue
            label, _, stream = str(ref).partition("/")
            inst = self.instruments.get(label)
            streams = [s.name for s in inst.streams()] if inst is not None else []
            if inst is None or stream not in streams:
                problems.append(Problem(f"{where}.inputs.{role}", f"{ref!r} is no stream of this session; " + (
                    f"{label} has: {', '.join(streams)}" if inst is not None else
                    f"instruments: {', '.join(self.instruments) or 'none'}")))
                continue
            bound_inputs[role] = (label, stream)
        for role in set(instruments) - set(commanded):
            problems.append(Problem(f"{where}.instruments.{role}", f"{cls.name} commands no {role!r}; "
                                    f"it commands: {', '.join(commanded) or 'nothing'}"))
        for role, names in commanded.items():
            label = instruments.get(role)
            inst = self.instruments.get(str(label))
            if inst is None:
                problems.append(Problem(f"{where}.instruments.{role}", f"required: the label of an instrument "
                                        f"of this session ({', '.join(self.instruments) or 'none'})"
                                        + (f"; {label!r} is not one" if label is not None else "")))
                continue
            not_live = [n for n in names if n not in inst.parameters or not inst.parameters[n].live]
            if not_live:
                problems.append(Problem(f"{where}.instruments.{role}", f"{inst.name} {label!r} has no live-settable "
                                        f"{', '.join(not_live)}, which {cls.name} sets"))
                continue
            bound_instruments[role] = inst
        return bound_inputs, bound_instruments, problems

    def _start_controllers(self) -> None:
        """Start every controller whose instruments all acquire (inputs and commanded ones)."""
        for runner in self.controllers.values():
            if not runner.running and runner.state != "failed" and self._bound_labels(runner) <= self._acquiring:
                runner.start()

    @staticmethod
    def _bound_labels(runner: ControllerRunner) -> set[str]:
        return {label for label, _ in runner.inputs.values()} | {i.label for i in runner.instruments.values()}

    # -- acquisition -----------------------------------------------------------------------------
    @property
    def acquiring(self) -> bool:
        return bool(self._acquiring)

    def _labels(self, instruments: Sequence[str] | None, what: str) -> list[str]:
        if not self.instruments:
            raise SessionError(f"no instruments to {what}; add one with add_instrument()")
        labels = list(self.instruments) if instruments is None else list(instruments)
        unknown = [label for label in labels if label not in self.instruments]
        if unknown or not labels:
            raise SessionError(f"cannot {what} {', '.join(unknown) or 'nothing'}; "
                               f"instruments of this session: {', '.join(self.instruments)}")
        return labels

    def start_acquisition(self, instruments: Sequence[str] | None = None) -> None:
        """Start instruments streaming to subscribers and controllers, without writing anything.

        ``instruments`` names the labels (default: all). Instruments already acquiring go on
        undisturbed; controllers start once all their instruments acquire. Use it to preview and
        align before recording; :meth:`start_recording` then switches the file on without
        restarting the devices.
        """
        with self._lock:
            if self._closed:
                raise SessionError(f"{self.path} is closed")
            labels = self._labels(instruments, "acquire")
            started = [label for label in labels if not self.instruments[label].running]
            for label in started:
                inst = self.instruments[label]
                inst.start(Emitter(label, self.router, self.clock, {s.name: s for s in inst.streams()}))
            self._acquiring |= set(labels)
            self._start_controllers()
            if started:
                self.events.emit("info", "session", "acquisition_started", f"acquiring {', '.join(started)}",
                                 instruments=started)

    def stop_acquisition(self, instruments: Sequence[str] | None = None) -> None:
        """Stop acquiring (all instruments, or ``instruments``); controllers bound to a stopped
        instrument stop before it. A recording ends once none of its instruments acquires, after
        the stopped ones have delivered their last samples."""
        with self._lock:
            labels = set(self._acquiring if instruments is None else instruments) & self._acquiring
            self._halt(labels)
            if self._recorder is not None and not set(self._recording) & self._acquiring:
                self.stop_recording()

    def _halt(self, labels: set[str]) -> None:
        """Stop the controllers bound to ``labels``, then those instruments (recording untouched)."""
        with self._lock:
            labels &= self._acquiring
            if not labels:
                return
            for runner in self.controllers.values():
                if self._bound_labels(runner) & labels:
                    runner.stop()
            for label in labels:
                self.instruments[label].stop()
            self._acquiring -= labels
            self.events.emit("info", "session", "acquisition_stopped", f"stopped acquiring {', '.join(sorted(labels))}",
                             instruments=sorted(labels))

    # -- recording -------------------------------------------------------------------------------
    @property
    def recording(self) -> bool:
        return self._recorder is not None

    def start_recording(self, instruments: Sequence[str] | None = None) -> None:
        """Declare the streams in the file, switch to SWMR and record ``instruments`` (default: all).

        Instruments not yet acquiring are started; those already acquiring (a preview) are not
        restarted. Controllers whose instruments are all recorded are recorded too.
        """
        with self._lock:
            self._require_writable("record")
            if self._recorder is not None:
                raise SessionError("already recording; stop_recording() first")
            labels = self._labels(instruments, "record")
            runners = [r for r in self.controllers.values() if self._bound_labels(r) <= set(labels)]
            paths: dict[tuple[str, str], str] = {}
            for group, source, specs in [("instruments", label, self.instruments[label].streams()) for label in labels] + \
                                        [("controllers", r.label, r.streams()) for r in runners]:
                for spec in specs:
                    schema.create_stream(self.file[group][source], spec)
                    paths[(source, spec.name)] = f"{group}/{source}/{spec.name}"
            self._write_pending_log()
            self.file.flush()
            self._commit()
            self.file.swmr_mode = True  # from here on no object or attribute may be created
            files.write_lock(self.path)  # tells `session check/close` a live writer has the file
            self._recorder = Recorder(self.file, self.router, self.events, paths)
            self._recorded_streams = list(paths)
            self._recorder.start()
            self._recording = labels
            self._recorded_controllers = [r.label for r in runners]
            self._reconnects_at_start = {label: inst.reconnects for label, inst in self.instruments.items()}
            self._record_start = time.monotonic()
            self.router.start_recording(labels + self._recorded_controllers)
            self.events.emit("info", "session", "recording_started", "recording started", instruments=labels,
                             controllers=self._recorded_controllers)
            self.start_acquisition(labels)
            for message in self.registry.notify("mirrorlab_recording_started", session=self):
                self.events.emit("warning", "session", "plugin_error", message)

    def stop_recording(self) -> dict[str, dict[str, int]]:
        """Write what is queued, leave SWMR; acquisition goes on. Returns per-stream statistics:
        ``{"<source>/<stream>": {"samples": written, "dropped": dropped}}`` of this recording."""
        with self._lock:
            if self._recorder is None:
                raise SessionError("not recording")
            self.router.stop_recording()
            self.recorded_seconds = time.monotonic() - self._record_start
            recorder, self._recorder = self._recorder, None
            self._last_recorder = recorder
            try:
                recorder.stop()
            finally:
                # Reopen without SWMR so attributes, results and new groups can be written again.
                self.file.close()
                self.file = h5py.File(self.path, "a", libver=LIBVER)
                files.remove_lock(self.path)
            stats = self._last_stats()
            for group, sources in (("instruments", self._recording), ("controllers", self._recorded_controllers)):
                for source in sources:
                    g = self.file[group][source]
                    if group == "instruments":
                        g.attrs["reconnects"] = self.instruments[source].reconnects - self._reconnects_at_start[source]
                    for name in g:
                        if isinstance(g[name], h5py.Group):
                            g[name].attrs["dropped"] = stats.get(f"{source}/{name}", {}).get("dropped", 0)
            dropped = sum(s["dropped"] for s in stats.values())
            self.events.emit("warning" if dropped else "info", "session", "recording_stopped",
                             f"recording stopped after {self.recorded_seconds:.1f} s: "
                             f"{sum(s['samples'] for s in stats.values())} samples written, {dropped} dropped",
                             statistics=stats, seconds=self.recorded_seconds)
            self._write_pending_log()
            self.file.flush()
            for message in self.registry.notify("mirrorlab_recording_stopped", session=self, statistics=stats):
                self.events.emit("warning", "session", "plugin_error", message)
            return stats

    def record(self, seconds: float | None = None,
               instruments: Sequence[str] | None = None) -> dict[str, dict[str, int]]:
        """Record, then stop; returns per-stream statistics (see :meth:`stop_recording`).

        Instruments that were not acquiring before are started for the recording and stopped
        after it (acquire → record → stop); a preview that was running goes on.

        Parameters
        ----------
        seconds
            Duration in s; ``None`` or 0 records until every recorded instrument has finished (a
            finite source such as a folder of frames or a virtual scene) or failed, as ``seconds = 0``
            does in a recipe's ``acquire`` step. A source that ends before ``seconds`` is reported
            with a ``source_ended`` warning event. :attr:`recorded_seconds` says how long it lasted.
        instruments
            Labels to record (default: all).

        :meth:`request_stop` (from any thread) ends it early, without an exception.
        """
        if seconds is not None and not seconds >= 0:
            raise ValidationError([Problem("seconds", f"{seconds} s: must be >= 0 (0 = until the sources end)")])
        seconds = seconds or None
        with self.operation():
            was_acquiring = set(self._acquiring)
            self.start_recording(instruments)
            recorder = self._recorder
            recorded = [self.instruments[label] for label in self._recording]
            try:
                self._wait_sources(recorded, seconds, "acquire", recorder)
            finally:
                # Instruments started for this recording stop first, so it holds all they acquired.
                self._halt({i.label for i in recorded} - was_acquiring)
                stats = self.stop_recording() if self._recorder is recorder else self._last_stats()
        return stats

    def preview(self, seconds: float | None = None, instruments: Sequence[str] | None = None) -> None:
        """Acquire without recording (to align, focus, check a loop), then stop what it started.

        ``seconds`` as in :meth:`record` (``None`` or 0: until the sources end or
        :meth:`request_stop`); subscribers and controllers get every sample, the file nothing.
        """
        if seconds is not None and not seconds >= 0:
            raise ValidationError([Problem("seconds", f"{seconds} s: must be >= 0 (0 = until the sources end)")])
        with self.operation():
            was_acquiring = set(self._acquiring)
            self.start_acquisition(instruments)
            labels = self._labels(instruments, "preview")
            try:
                self._wait_sources([self.instruments[label] for label in labels], seconds or None, "preview")
            finally:
                self._halt(set(labels) - was_acquiring)

    def _wait_sources(self, sources: list[Instrument], seconds: float | None, what: str,
                      recorder: Recorder | None = None) -> None:
        """Wait ``seconds`` (``None``: until the sources end), a stop request, or a failure."""
        ended: set[str] = set()
        start = time.monotonic()
        while seconds is None or (time.monotonic() - start) < seconds:
            elapsed = time.monotonic() - start
            self.events.progress(what, round(elapsed, 1), seconds, "recording" if recorder else "previewing")
            if self._cancel.wait(0.1 if seconds is None else min(0.1, max(0.0, seconds - elapsed))):
                self.events.emit("info", "session", "stopped_on_request",
                                 f"{what} ended on request after {time.monotonic() - start:.1f} s")
                break
            self._report_ended(sources, ended, time.monotonic() - start, seconds)
            if recorder is not None and (self._recorder is not recorder or recorder.error is not None):
                break  # stopped from another thread, or the recorder failed
            if all(i.failed is not None for i in sources):
                self.events.emit("error", "session", "all_failed", "every instrument failed; stopping")
                break
            if not any(i.running for i in sources):
                break  # every source has ended
        done = time.monotonic() - start
        self.events.progress(what, done, done if seconds is None else seconds, "recording" if recorder else "previewing")

    def _last_stats(self) -> dict[str, dict[str, int]]:
        """Statistics of the last recording, every recorded stream (see :meth:`stop_recording`)."""
        recorder, counted = self._last_recorder, self.router.stats
        return {f"{source}/{stream}": {"samples": recorder.written.get((source, stream), 0) if recorder else 0,
                                       "dropped": counted[(source, stream)].dropped_samples
                                       if (source, stream) in counted else 0}
                for source, stream in self._recorded_streams}

    # -- cancellation and observation ---------------------------------------------------------------
    @contextlib.contextmanager
    def operation(self) -> Iterator[None]:
        """Mark long work (a recording, a recipe, an algorithm run) that :meth:`request_stop` ends.

        Nested operations are one: a stop requested before the outermost one started is forgotten,
        one requested during it ends every nested operation.
        """
        with self._lock:
            if self._operations == 0:
                self._cancel.clear()
            self._operations += 1
        try:
            yield
        finally:
            with self._lock:
                self._operations -= 1

    def request_stop(self) -> None:
        """Ask the running :meth:`record`, recipe step or algorithm run to end (from any thread).

        Cooperative: the recording stops and is written, a running algorithm ends as ``cancelled``
        at its next progress report, a recipe runs no further step. Returns at once.
        """
        self._cancel.set()
        self.events.emit("info", "session", "stop_requested", "stop requested")

    @property
    def stop_requested(self) -> bool:
        return self._cancel.is_set()

    def snapshot(self) -> SessionSnapshot:
        """An immutable summary of the live session; never calls a device or the file (≥ 50 Hz safe)."""
        counts = self.router.counts()
        recorder = self._recorder
        recorded = set(self._recording) if recorder is not None else set()
        now = time.monotonic()
        instruments = {}
        for label, inst in list(self.instruments.items()):
            samples, dropped = counts.get(label, (0, 0))
            deadline = inst.reconnect_deadline
            instruments[label] = InstrumentSnapshot(
                label, inst.name, inst.state, label in self._acquiring, label in recorded,
                self.router.last_time.get(label), samples, dropped,
                inst.reconnects - self._reconnects_at_start.get(label, 0),
                None if deadline is None else max(0.0, deadline - now), inst.last_status,
                "" if inst.failed is None else str(inst.failed))
        controllers = {
            label: ControllerSnapshot(label, r.controller.name, r.state, r.commands_sent, r.commands_failed,
                                      r.latency_stats(), "" if r.error is None else str(r.error),
                                      r.commands_superseded)
            for label, r in list(self.controllers.items())}
        last = recorder or self._last_recorder
        queue = self.router.recorder_queue
        rec = RecorderSnapshot(recorder is not None, queue.qsize(), queue.maxsize,
                               last.bytes_written if last is not None else 0,
                               "" if last is None or last.error is None else str(last.error))
        return SessionSnapshot(self.clock.now(), str(self.path), bool(self._acquiring), recorder is not None,
                               now - self._record_start if recorder is not None else self.recorded_seconds,
                               MappingProxyType(instruments), MappingProxyType(controllers), rec)

    def _report_ended(self, recorded: list[Instrument], ended: set[str], elapsed: float,
                      seconds: float | None) -> None:
        """Warn once per instrument whose source ended (not failed) before the requested duration."""
        for inst in recorded:
            if inst.label in ended or inst.running:
                continue
            ended.add(inst.label)
            if seconds is not None and inst.failed is None:
                self.events.emit("warning", inst.label, "source_ended",
                                 f"source ended after about {elapsed:.1f} s, before the requested {seconds:g} s; "
                                 "the recording holds what it delivered",
                                 elapsed=elapsed, requested=seconds)

    # -- writing other data ----------------------------------------------------------------------
    def _write_pending_log(self) -> None:
        events = self.events.take_pending()
        if events and self.writable:
            schema.append(self.file["log"], schema.log_rows(events))

    def write_group(self, path: str, arrays: Mapping[str, Any], attrs: Mapping[str, Any] | None = None) -> None:
        """Write arrays into a new group (e.g. ``calibration/cam`` or ``truth/markers``)."""
        self._require_writable(f"write {path}")
        if path.strip("/") in self.file:
            raise SessionError(f"{path} already exists in {self.path}; groups are never overwritten")
        self._commit()
        g = self.file.create_group(path.strip("/"))
        for name, value in arrays.items():
            g.create_dataset(name, data=np.asarray(value))
        for key, value in (attrs or {}).items():
            if isinstance(value, (dict, list, tuple)):
                schema.set_json(g, key, value)
            else:
                g.attrs[key] = value
        self.file.flush()

    # -- algorithms ------------------------------------------------------------------------------
    def run(self, algorithm: str | type[Algorithm], inputs: Mapping[str, str | np.ndarray],
            parameters: Mapping[str, Any] | None = None,
            progress: Callable[[float, float | None, str], None] | None = None, *,
            label: str | None = None, input_units: Mapping[str, str] | None = None) -> ResultRef:
        """Run an algorithm and store its result with provenance.

        Parameters
        ----------
        algorithm
            Registered name or class.
        inputs
            Input name → dataset path in this file (``"/instruments/cam/frames/data"``), result
            reference (``"@algorithm/output"``, ``"@label/output"``, see :meth:`resolve`) or array.
        parameters
            Algorithm parameters (validated; defaults filled in and stored).
        progress
            Optional ``progress(done, total, message)`` callback (progress events are emitted too).
        label
            Run label (``as = "..."`` in a recipe's ``run`` step) so that ``@label/output`` names
            this run's output even after later runs of the same algorithm. At most one successful
            run of a session carries a label; see :func:`~mirrorlab.core.algorithms.label_problem`.
        input_units
            Input name → unit of an input given as an array (or as a dataset without a ``unit``
            attribute). An output unit declared as ``{name}/s`` becomes ``mm/s`` when input
            ``name`` is in ``mm``; a dataset's own unit takes precedence.

        Returns the :class:`ResultRef`. The run is written as ``/results/<algorithm>/<run-id>``:
        its outputs first, each with the ``unit`` and ``description`` of its declared
        :class:`~mirrorlab.core.algorithms.Port`, and its ``status`` last, so a run whose writing was
        interrupted has no status and reads as ``incomplete``. A failed run is stored with
        ``status = "failed"`` and its error, a run stopped by :meth:`request_stop` (the event
        ``self._cancel``) with ``status = "cancelled"``; neither has outputs, and nothing earlier
        is overwritten.
        """
        self._require_writable("write results")
        cls = self.registry.algorithm(algorithm) if isinstance(algorithm, str) else algorithm
        label = label or ""
        if label:
            self._check_label(label, f"{cls.name}.label")
        arrays, sources, units = {}, {}, {}
        for name, value in inputs.items():
            if isinstance(value, str):
                sources[name] = self.resolve(value, f"inputs.{name}")
                units[name] = _dataset_unit(self.file[sources[name]])
            else:
                arrays[name] = np.asarray(value)
        for name, unit in (input_units or {}).items():
            if name in inputs and not units.get(name):
                units[name] = unit
        datasets = dict(sources)

        def report(done: float, total: float | None, message: str) -> None:
            self.events.progress(cls.name, done, total, message)
            if progress is not None:
                progress(done, total, message)

        self._commit()
        started = utc_now_iso()
        # While the inputs are read and the algorithm runs, the file is in SWMR mode: if this process
        # is killed then, the file opens through SWMR and `session close` repairs it (killed outside
        # SWMR mode, it would need HDF5's h5clear tool). Outputs are written after, in normal mode.
        with self.operation(), self.shared_for_reading(required=False):  # request_stop() cancels at the next progress report
            # Datasets are opened only now (HDF5 cannot enter SWMR mode while an object written in an
            # older format is open); read here, or in chunks by the executor's workers.
            arrays = {name: self.file[datasets[name]] if name in datasets else arrays[name] for name in inputs}
            context = RunContext(report, self._cancel)
            if self.executor is None:
                arrays, digests = read_hashed(arrays)
                outcome = execute(cls, arrays, parameters or {}, context)
            else:  # the executor hashes the inputs as it reads them
                outcome, digests = self.executor(self, cls, arrays, parameters or {}, context)
            sources.update({name: "sha256:" + digests[name]["sha256"] for name in arrays if name not in sources})
        group = self.file.require_group(f"results/{cls.name}")
        run_id = f"run-{len(group) + 1:04d}"
        while run_id in group:  # never overwrite
            run_id = f"run-{int(run_id[4:]) + 1:04d}"
        g = group.create_group(run_id)
        g.attrs.update({"algorithm": cls.name, "plugin_version": cls.version, "label": label,
                        "started_utc": started})
        schema.set_json(g, "parameters", to_jsonable(outcome.params))
        schema.set_json(g, "inputs", sources)
        schema.set_json(g, "input_sha256", digests)
        if self.executor is not None:
            schema.set_json(g, "executor", self.executor.provenance)
        self.file.flush()  # the run's provenance is on disk before its outputs
        ports = {p.name: p for p in cls.outputs}
        try:
            for name, value in outcome.outputs.items():
                ds = g.create_dataset(name, data=value)
                ds.attrs["unit"] = _unit(ports[name].unit, units)
                ds.attrs["description"] = ports[name].description
            g.attrs.update({"finished_utc": utc_now_iso(), "error": outcome.error})
            if outcome.traceback:
                g.attrs["traceback"] = outcome.traceback
            self.file.flush()  # everything of the run is on disk before the status says so
            g.attrs["status"] = outcome.status
        except OSError as exc:  # a full disk: the run stays without status, read as "incomplete"
            self.events.emit("error", cls.name, "result_incomplete",
                             f"{g.name}: writing the run failed, it is left without status (incomplete)")
            raise files.os_error(self.path, exc, "write to") from exc
        ref = ResultRef(cls.name, run_id, outcome.status, outcome.error, label)
        self.events.emit({"ok": "info", "cancelled": "warning"}.get(outcome.status, "error"), cls.name,
                         "result_written", f"{ref.path}{f' ({label})' if label else ''}: {outcome.status}"
                         f"{' — ' + outcome.error if outcome.error else ''}", label=label)
        self._write_pending_log()
        self.file.flush()
        for message in self.registry.notify("mirrorlab_result_written", session=self, result=ref):
            self.events.emit("warning", "session", "plugin_error", message)
        return ref

    @contextlib.contextmanager
    def shared_for_reading(self, required: bool = True) -> Iterator[None]:
        """Let other processes read the file (SWMR) during the block; this session writes nothing meanwhile.

        Everything is flushed, the file switches to SWMR mode (as while recording, so readers open it
        with :func:`~mirrorlab.core.store.files.open_readonly`), and is reopened writable after.
        HDF5 refuses SWMR mode while an object written in a format older than HDF5 1.10 is open
        (one added to the file by another program): that raises :class:`SessionError` or, with
        ``required=False``, runs the block unshared.
        """
        self._require_writable("share the file for reading")
        if self._shared:  # already shared by an enclosing block
            yield
            return
        self._write_pending_log()
        self._commit()
        self.file.flush()
        try:
            self.file.swmr_mode = True
        except RuntimeError as exc:  # h5py's error for "Unable to start swmr writing (...)"
            if required:
                raise SessionError(f"{self.path} cannot be shared with other processes while it is open here "
                                   f"({exc}); close what holds its datasets open, or run without workers") from exc
            yield
            return
        files.write_lock(self.path)
        self._shared += 1
        try:
            yield
        finally:
            self._shared -= 1
            self.file.close()
            self.file = files.open_writable(self.path)
            files.remove_lock(self.path)

    def _check_label(self, label: str, key: str) -> None:
        """Raise :class:`ValidationError` unless ``label`` can name a new successful run."""
        reason = label_problem(label, {*self.registry.names("algorithm"), *self.file.get("results", {})})
        taken = [r for r in self.results() if r.label == label and r.status == "ok"]
        if reason is None and taken:
            reason = f"label {label!r} already names {taken[0].path}; choose another label"
        if reason is not None:
            raise ValidationError([Problem(key, reason)])

    def resolve(self, reference: str, key: str = "dataset") -> str:
        """The dataset path a reference names.

        ``/absolute/path`` names itself; ``@name/output`` names ``output`` of the successful run
        labelled ``name`` if there is one, else of the latest successful run of the algorithm
        ``name`` in this session (how recipe steps chain results).
        """
        if not reference.startswith("@"):
            path = reference
        else:
            name, _, output = reference[1:].partition("/")
            runs = [r for r in self.results() if r.status == "ok" and name in (r.label, r.algorithm)]
            labelled = [r for r in runs if r.label == name]
            run = (labelled or runs or [None])[-1]
            if run is None or not output:
                raise ValidationError([Problem(key, f"{reference!r}: no successful run of {name!r} (an algorithm "
                                               "or a run label) in this session yet (write @algorithm/output "
                                               "or @label/output after its step)")])
            path = f"{run.path}/{output}"
            if output not in self.file[run.path]:
                raise ValidationError([Problem(key, f"{reference!r}: {run.path} has no output {output!r}; it has: "
                                               f"{', '.join(self.file[run.path]) or 'none'}")])
        if path.strip("/") not in self.file or not isinstance(self.file[path], h5py.Dataset):
            raise ValidationError([Problem(key, f"no dataset {path!r} in {self.path}")])
        return path

    def results(self, algorithm: str | None = None) -> list[ResultRef]:
        """Stored runs, oldest first (of one algorithm, or all); a run without status is ``incomplete``."""
        out = []
        for name, group in files.members(self.file, "results"):
            if algorithm is not None and name != algorithm:
                continue
            for run_id, g in files.members(group):
                out.append(ResultRef(name, run_id, schema.run_status(g), schema.attr_str(g, "error"),
                                     schema.attr_str(g, "label")))
        return out

    def result(self, ref: ResultRef | str) -> ResultData:
        """Read one stored run (by :class:`ResultRef` or path ``/results/<alg>/<run-id>``)."""
        path = ref.path if isinstance(ref, ResultRef) else ref
        if path.strip("/") not in self.file:
            raise SessionError(f"no result {path} in {self.path}")
        g = self.file[path]
        attrs = {k: (schema.text(v) if isinstance(v, (bytes, str)) else v) for k, v in g.attrs.items()}
        for key in ("parameters", "inputs", "input_sha256"):
            attrs[key] = schema.get_json(g, key, {})
        attrs["status"] = schema.run_status(g)
        parts = path.strip("/").split("/")
        ref = ResultRef(parts[1], parts[2], attrs["status"], attrs.get("error", ""), attrs.get("label", ""))
        return ResultData(ref, {k: g[k][()] for k in g}, attrs)

    # -- reading ---------------------------------------------------------------------------------
    def stream(self, source: str, stream: str) -> StreamData:
        """A recorded stream of an instrument or a controller (times in session seconds); usable as
        ``times, data = ...``."""
        key = next((k for k in (f"instruments/{source}/{stream}", f"controllers/{source}/{stream}") if k in self.file),
                   None)
        if key is None:
            raise SessionError(f"no stream {source}/{stream} in {self.path}; "
                               "`mirrorlab session info FILE` lists the streams")
        g = self.file[key]
        for ds in (g["data"], g["time"]):
            if self.crashed or self.file.swmr_mode:
                ds.refresh()
        n = min(g["data"].shape[0], g["time"].shape[0])
        attrs = {k: (schema.text(v) if isinstance(v, (bytes, str)) else v) for k, v in g.attrs.items()}
        return StreamData(g["time"][:n], g["data"][:n], schema.attr_str(g, "unit"), attrs)

    def describe(self) -> dict[str, Any]:
        """JSON-ready summary: attributes, instruments and controllers with their streams, results, log size."""
        instruments = {label: {"plugin": schema.attr_str(g, "plugin"), "version": schema.attr_str(g, "version"),
                               "settings": schema.get_json(g, "settings", {}),
                               "identity": schema.get_json(g, "identity", {}), "streams": self._streams(g)}
                       for label, g in files.members(self.file, "instruments")}
        controllers = {label: {"plugin": schema.attr_str(g, "plugin"), "version": schema.attr_str(g, "version"),
                               "settings": schema.get_json(g, "settings", {}),
                               "inputs": schema.get_json(g, "inputs", {}),
                               "instruments": schema.get_json(g, "instruments", {}), "streams": self._streams(g)}
                       for label, g in files.members(self.file, "controllers")}
        return {"path": str(self.path), "attributes": self.attrs, "crashed": self.crashed,
                "writer": files.live_writer(self.path) if self.crashed else None,
                "instruments": instruments, "controllers": controllers, "groups": self._other_groups(),
                "results": [{"path": r.path, "status": r.status, "error": r.error, "label": r.label,
                             "outputs": {name: {"shape": list(ds.shape), "dtype": str(ds.dtype),
                                                "unit": schema.attr_str(ds, "unit")}
                                         for name, ds in files.members(self.file, r.path)}}
                            for r in self.results()],
                "log_events": int(self.file["log"].shape[0]) if "log" in self.file else 0}

    @staticmethod
    def _streams(g: h5py.Group) -> dict[str, dict[str, Any]]:
        return {name: {"samples": int(min(sg["data"].shape[0], sg["time"].shape[0])),
                       "shape": list(sg["data"].shape[1:]), "dtype": str(sg["data"].dtype),
                       "unit": schema.attr_str(sg, "unit")}
                for name, sg in files.members(g) if isinstance(sg, h5py.Group) and "data" in sg}

    def _other_groups(self) -> dict[str, dict[str, Any]]:
        """What sits outside config, instruments, results and log (/calibration, /truth, /report,
        /markers...): a top-level group that holds datasets, else each of its groups, with their
        numbers of datasets and groups and their ``description``."""
        summary = {}
        for name, top in files.members(self.file):
            if name in ("config", "instruments", "controllers", "results") or not isinstance(top, h5py.Group):
                continue
            children = files.members(top)
            holds_data = any(isinstance(obj, h5py.Dataset) for _, obj in children)
            parts = [(f"/{name}", top)] if holds_data else [(f"/{name}/{k}", g) for k, g in children]
            for path, g in parts:
                kinds = [isinstance(obj, h5py.Group) for _, obj in files.members(g)]
                summary[path] = {"datasets": kinds.count(False), "groups": kinds.count(True),
                                 "description": schema.attr_str(g, "description")}
        return summary

    def log(self) -> list[dict[str, Any]]:
        """The stored structured events."""
        return schema.read_log(self.file)

    # -- closing ---------------------------------------------------------------------------------
    def close(self, status: str | None = None, reason: str = "") -> None:
        """Stop recording and acquisition, close instruments and simulators, set ``status``, close the file.

        ``status`` defaults to ``closed`` for a session created here and to its stored status for
        an opened one (analysis never turns an aborted recording into a closed one). ``reason``
        (e.g. ``"interrupted (Ctrl-C) during step 2"``) is logged with the closing event. A new
        session closed ``aborted`` before it held anything is deleted (see :meth:`create`).
        """
        with self._lock:
            self._close(status, reason)

    def _close(self, status: str | None, reason: str) -> None:
        if self._closed:
            return
        if status is None:
            status = "closed" if self._created else self.status
        if self.writable and status not in ("closed", "aborted"):
            raise ValueError("status must be 'closed' or 'aborted'")
        errors: list[BaseException] = []
        try:
            if self._recorder is not None:
                try:
                    self.stop_recording()
                except Exception as exc:  # keep closing: instruments, simulators, status
                    errors.append(exc)
                    status = "aborted"
            self.stop_acquisition()
            self.router.close_all()
            for inst in self.instruments.values():
                inst.close()
            for label in list(self._simulators):
                self._stop_simulator(label)
            if self.writable:
                for message in self.registry.notify("mirrorlab_session_closing", session=self, status=status):
                    self.events.emit("warning", "session", "plugin_error", message)
                self.events.emit("info", "session", "closed", f"session {status}" + (f": {reason}" if reason else ""),
                                 **({"reason": reason} if reason else {}))
                self._write_pending_log()
                self.file.attrs["status"] = status
                if status == "closed":
                    self._commit()
        finally:
            self._closed = True
            self.file.close()
            if self._draft is not None:  # a start that failed before the file held anything
                self._draft.unlink(missing_ok=True)
        if errors:
            raise errors[0]
