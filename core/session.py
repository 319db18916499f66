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

import hashlib
import json
import os
import platform
import socket
import sys
import time
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from .algorithms import Algorithm, ResultRef, RunContext, execute
from .clock import SessionClock, utc_now_iso
from .devices import Instrument, SerialInstrument, SimulatorServer
from .errors import Problem, SessionError, SessionExistsError, ValidationError
from .events import EventBus
from .params import Parameter, ParameterSet, to_jsonable
from .registry import Registry, get_registry
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
        self.clock = SessionClock()
        self.events = EventBus(self.clock)
        self.router = StreamRouter(on_overflow=self._on_overflow)
        self.instruments: dict[str, Instrument] = {}
        self._simulators: dict[str, SimulatorServer] = {}
        self._recorder: Recorder | None = None
        self._recording: list[str] = []
        self._closed = False
        self._created = False
        self._draft: Path | None = None  # the file as created, until _commit (see create)
        #: How long the last recording lasted (start to stop of the instruments), s.
        self.recorded_seconds = 0.0
        self._record_start = 0.0
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
            f.attrs.update({
                "mirrorlab_schema": schema.SCHEMA_VERSION,
                "mirrorlab_version": mirrorlab_version(),
                "session_id": str(uuid.uuid4()),
                "created_utc": utc_now_iso(),
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
            "plugins": {name: {"source": p.source, "distribution": p.distribution, "version": p.version,
                               "ok": p.ok, "provides": p.provides} for name, p in registry.plugins.items()},
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
                       simulator: Mapping[str, Any] | None = None, timeout: float = 2.0) -> Instrument:
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
        """
        self._require_writable("add an instrument")
        if label in self.instruments or f"instruments/{label}" in self.file:
            raise SessionError(f"an instrument labelled {label!r} is already in this session; pick another label")
        cls = self.registry.instrument(plugin)
        sim_options = SIMULATOR_OPTIONS.validate(dict(simulator or {}), where=f"instruments.{label}.simulator")
        instrument: Instrument = cls(label, port, settings, timeout, report=self._reporter(label))
        # Only a device on a port has a simulator to serve; other sources (files, a virtual
        # scene) are their own simulation.
        served = simulate and cls.needs_port(instrument.settings)
        if served:
            server = self._start_simulator(cls, instrument.settings, sim_options, label)
            instrument.port = server.url
        try:
            instrument.connect()
            instrument.identify()
            if served and isinstance(instrument, SerialInstrument):
                instrument.simulate_query(f"SIM:SEED {sim_options['seed']}")
                instrument.simulate_query(f"SIM:CLOCK {sim_options['clock']}")
            instrument.configure()
        except BaseException:
            instrument.close()
            self._stop_simulator(label)
            raise
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

    def _start_simulator(self, cls: type[Instrument], settings: dict[str, Any], options: dict[str, Any],
                         label: str) -> SimulatorServer:
        make = getattr(cls, "make_simulator", None)
        if make is not None:
            model = make(settings, options["seed"])
        elif getattr(cls, "simulator", None) is not None:
            model = cls.simulator(seed=options["seed"])
        else:
            raise SessionError(f"instrument plugin {cls.name!r} has no simulator; set simulate = false "
                               "and give the port of a real device")
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

    def subscribe(self, instrument: str, stream: str, maxlen: int = 1024) -> Subscription:
        """Live view of a stream (latest block, ring buffer), independent of the file."""
        return self.router.subscribe(instrument, stream, maxlen)

    # -- recording -------------------------------------------------------------------------------
    @property
    def recording(self) -> bool:
        return self._recorder is not None

    def start_recording(self, instruments: Sequence[str] | None = None) -> None:
        """Declare the streams in the file, switch to SWMR and start the instruments.

        ``instruments`` names the labels to record (default: all of them).
        """
        self._require_writable("record")
        if self._recorder is not None:
            raise SessionError("already recording")
        if not self.instruments:
            raise SessionError("no instruments to record; add one with add_instrument()")
        labels = list(self.instruments) if instruments is None else list(instruments)
        unknown = [label for label in labels if label not in self.instruments]
        if unknown or not labels:
            raise SessionError(f"cannot record {', '.join(unknown) or 'nothing'}; "
                               f"instruments of this session: {', '.join(self.instruments)}")
        emitters = {}
        for label in labels:
            specs = self.instruments[label].streams()
            group = self.file["instruments"][label]
            for spec in specs:
                schema.create_stream(group, spec)
            emitters[label] = Emitter(label, self.router, self.clock, {s.name: s for s in specs})
        self._write_pending_log()
        self.file.flush()
        self._commit()
        self.file.swmr_mode = True  # from here on no object or attribute may be created
        files.write_lock(self.path)  # tells `session check/close` a live writer has the file
        self.router.recording = True
        self._recorder = Recorder(self.file, self.router, self.events)
        self._recorder.start()
        self._recording = labels
        self._record_start = time.monotonic()
        self.events.emit("info", "session", "recording_started", "recording started", instruments=labels)
        for label in labels:
            self.instruments[label].start(emitters[label])
        for message in self.registry.notify("mirrorlab_recording_started", session=self):
            self.events.emit("warning", "session", "plugin_error", message)

    def stop_recording(self) -> dict[str, dict[str, int]]:
        """Stop instruments, write what is queued, leave SWMR; returns per-stream statistics."""
        if self._recorder is None:
            raise SessionError("not recording")
        for label in self._recording:
            self.instruments[label].stop()
        self.router.recording = False
        self.recorded_seconds = time.monotonic() - self._record_start
        recorder, self._recorder = self._recorder, None
        try:
            recorder.stop()
        finally:
            # Reopen without SWMR so attributes, results and new groups can be written again.
            self.file.close()
            self.file = h5py.File(self.path, "a", libver=LIBVER)
            files.remove_lock(self.path)
        stats = {}
        for (inst, stream), st in self.router.stats.items():
            stats[f"{inst}/{stream}"] = {"samples": recorder.written.get((inst, stream), 0),
                                         "dropped": st.dropped_samples}
        for label, inst in self.instruments.items():
            g = self.file["instruments"][label]
            g.attrs["reconnects"] = inst.reconnects
            for name in g:
                if isinstance(g[name], h5py.Group):
                    g[name].attrs["dropped"] = stats.get(f"{label}/{name}", {}).get("dropped", 0)
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

        Parameters
        ----------
        seconds
            Duration in s; ``None`` or 0 records until every recorded instrument has finished (a
            finite source such as a folder of frames or a virtual scene) or failed, as ``seconds = 0``
            does in a recipe's ``acquire`` step. A source that ends before ``seconds`` is reported
            with a ``source_ended`` warning event. :attr:`recorded_seconds` says how long it lasted.
        instruments
            Labels to record (default: all).
        """
        if seconds is not None and not seconds >= 0:
            raise ValidationError([Problem("seconds", f"{seconds} s: must be >= 0 (0 = until the sources end)")])
        seconds = seconds or None
        self.start_recording(instruments)
        recorded = [self.instruments[label] for label in self._recording]
        ended: set[str] = set()
        try:
            start = time.monotonic()
            while seconds is None or (time.monotonic() - start) < seconds:
                elapsed = time.monotonic() - start
                self.events.progress("acquire", round(elapsed, 1), seconds, "recording")
                time.sleep(0.1 if seconds is None else min(0.1, max(0.0, seconds - elapsed)))
                self._report_ended(recorded, ended, time.monotonic() - start, seconds)
                if self._recorder is not None and self._recorder.error is not None:
                    break
                if all(i.failed is not None for i in recorded):
                    self.events.emit("error", "session", "all_failed", "every instrument failed; stopping")
                    break
                if not any(i.running for i in recorded):
                    break  # every source has ended
            done = time.monotonic() - start
            self.events.progress("acquire", done, done if seconds is None else seconds, "recording")
        finally:
            stats = self.stop_recording()
        return stats

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
            progress: Callable[[float, float | None, str], None] | None = None) -> ResultRef:
        """Run an algorithm and store its result with provenance.

        Parameters
        ----------
        algorithm
            Registered name or class.
        inputs
            Input name → dataset path in this file (``"/instruments/cam/frames/data"``) or array.
        parameters
            Algorithm parameters (validated; defaults filled in and stored).
        progress
            Optional ``progress(done, total, message)`` callback (progress events are emitted too).

        Returns the :class:`ResultRef`; a failed run is stored with ``status = "failed"`` and its
        error, and nothing earlier is overwritten.
        """
        self._require_writable("write results")
        cls = self.registry.algorithm(algorithm) if isinstance(algorithm, str) else algorithm
        arrays, sources = {}, {}
        for name, value in inputs.items():
            if isinstance(value, str):
                path = self.resolve(value, f"inputs.{name}")
                arrays[name] = self.file[path][()]
                sources[name] = path
            else:
                arrays[name] = np.asarray(value)
                sources[name] = "<array>"

        def report(done: float, total: float | None, message: str) -> None:
            self.events.progress(cls.name, done, total, message)
            if progress is not None:
                progress(done, total, message)

        self._commit()
        started = utc_now_iso()
        outcome = execute(cls, arrays, parameters or {}, RunContext(report))
        finished = utc_now_iso()
        group = self.file.require_group(f"results/{cls.name}")
        run_id = f"run-{len(group) + 1:04d}"
        while run_id in group:  # never overwrite
            run_id = f"run-{int(run_id[4:]) + 1:04d}"
        g = group.create_group(run_id)
        g.attrs.update({"algorithm": cls.name, "plugin_version": cls.version, "started_utc": started,
                        "finished_utc": finished, "status": outcome.status, "error": outcome.error})
        schema.set_json(g, "parameters", to_jsonable(outcome.params))
        schema.set_json(g, "inputs", sources)
        if outcome.traceback:
            g.attrs["traceback"] = outcome.traceback
        for name, value in outcome.outputs.items():
            g.create_dataset(name, data=np.asarray(value))
        ref = ResultRef(cls.name, run_id, outcome.status, outcome.error)
        self.events.emit("info" if outcome.status == "ok" else "error", cls.name, "result_written",
                         f"{ref.path}: {outcome.status}{' — ' + outcome.error if outcome.error else ''}")
        self._write_pending_log()
        self.file.flush()
        for message in self.registry.notify("mirrorlab_result_written", session=self, result=ref):
            self.events.emit("warning", "session", "plugin_error", message)
        return ref

    def resolve(self, reference: str, key: str = "dataset") -> str:
        """The dataset path a reference names.

        ``/absolute/path`` names itself; ``@algorithm/output`` names ``output`` of the latest
        successful run of ``algorithm`` in this session (how recipe steps chain results).
        """
        if reference.startswith("@"):
            algorithm, _, output = reference[1:].partition("/")
            runs = [r for r in self.results(algorithm) if r.status == "ok"]
            if not runs or not output:
                raise ValidationError([Problem(key, f"{reference!r}: no successful run of {algorithm!r} "
                                               "in this session yet (write @algorithm/output after its step)")])
            path = f"{runs[-1].path}/{output}"
        else:
            path = reference
        if path.strip("/") not in self.file or not isinstance(self.file[path], h5py.Dataset):
            raise ValidationError([Problem(key, f"no dataset {path!r} in {self.path}")])
        return path

    def results(self, algorithm: str | None = None) -> list[ResultRef]:
        """Stored runs, oldest first (of one algorithm, or all)."""
        out = []
        for name, group in files.members(self.file, "results"):
            if algorithm is not None and name != algorithm:
                continue
            for run_id, g in files.members(group):
                out.append(ResultRef(name, run_id, schema.attr_str(g, "status"), schema.attr_str(g, "error")))
        return out

    def result(self, ref: ResultRef | str) -> ResultData:
        """Read one stored run (by :class:`ResultRef` or path ``/results/<alg>/<run-id>``)."""
        path = ref.path if isinstance(ref, ResultRef) else ref
        if path.strip("/") not in self.file:
            raise SessionError(f"no result {path} in {self.path}")
        g = self.file[path]
        attrs = {k: (schema.text(v) if isinstance(v, (bytes, str)) else v) for k, v in g.attrs.items()}
        for key in ("parameters", "inputs"):
            attrs[key] = schema.get_json(g, key, {})
        parts = path.strip("/").split("/")
        ref = ResultRef(parts[1], parts[2], attrs.get("status", ""), attrs.get("error", ""))
        return ResultData(ref, {k: g[k][()] for k in g}, attrs)

    # -- reading ---------------------------------------------------------------------------------
    def stream(self, instrument: str, stream: str) -> StreamData:
        """A recorded stream (times in session seconds); usable as ``times, data = ...``."""
        key = f"instruments/{instrument}/{stream}"
        if key not in self.file:
            raise SessionError(f"no stream {instrument}/{stream} in {self.path}; "
                               "`mirrorlab session info FILE` lists the streams")
        g = self.file[key]
        for ds in (g["data"], g["time"]):
            if self.crashed or self.file.swmr_mode:
                ds.refresh()
        n = min(g["data"].shape[0], g["time"].shape[0])
        attrs = {k: (schema.text(v) if isinstance(v, (bytes, str)) else v) for k, v in g.attrs.items()}
        return StreamData(g["time"][:n], g["data"][:n], schema.attr_str(g, "unit"), attrs)

    def describe(self) -> dict[str, Any]:
        """JSON-ready summary: attributes, instruments with their streams, results, log size."""
        instruments = {}
        for label, g in files.members(self.file, "instruments"):
            streams = {}
            for name, sg in files.members(g):
                if isinstance(sg, h5py.Group) and "data" in sg:
                    streams[name] = {"samples": int(min(sg["data"].shape[0], sg["time"].shape[0])),
                                     "shape": list(sg["data"].shape[1:]), "dtype": str(sg["data"].dtype),
                                     "unit": schema.attr_str(sg, "unit")}
            instruments[label] = {"plugin": schema.attr_str(g, "plugin"), "version": schema.attr_str(g, "version"),
                                  "settings": schema.get_json(g, "settings", {}),
                                  "identity": schema.get_json(g, "identity", {}), "streams": streams}
        return {"path": str(self.path), "attributes": self.attrs, "crashed": self.crashed,
                "writer": files.live_writer(self.path) if self.crashed else None,
                "instruments": instruments, "groups": self._other_groups(),
                "results": [{"path": r.path, "status": r.status, "error": r.error} for r in self.results()],
                "log_events": int(self.file["log"].shape[0]) if "log" in self.file else 0}

    def _other_groups(self) -> dict[str, dict[str, Any]]:
        """What sits outside config, instruments, results and log (/calibration, /truth, /report,
        /markers...): a top-level group that holds datasets, else each of its groups, with their
        numbers of datasets and groups and their ``description``."""
        summary = {}
        for name, top in files.members(self.file):
            if name in ("config", "instruments", "results") or not isinstance(top, h5py.Group):
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
    def close(self, status: str | None = None) -> None:
        """Stop recording if needed, close instruments and simulators, set ``status``, close the file.

        ``status`` defaults to ``closed`` for a session created here and to its stored status for
        an opened one (analysis never turns an aborted recording into a closed one). A new session
        closed ``aborted`` before it held anything is deleted (see :meth:`create`).
        """
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
            for inst in self.instruments.values():
                inst.stop()
                inst.close()
            for label in list(self._simulators):
                self._stop_simulator(label)
            if self.writable:
                for message in self.registry.notify("mirrorlab_session_closing", session=self, status=status):
                    self.events.emit("warning", "session", "plugin_error", message)
                self.events.emit("info", "session", "closed", f"session {status}")
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
