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
    ...     s.status, frames.shape[1:], s.read("/instruments/cam/frames/data", 0).shape
    ('closed', (32, 512), (32, 512))

Files are opened read-only unless ``writable=True`` (or created). Recording switches the file to
SWMR mode, so another process may read it while it grows; results are written after recording,
each algorithm run into a new ``/results/<algorithm>/<run-id>`` group that is never overwritten.

:class:`Session` is a facade over three parts, each with one job (their methods document the parameters):

* :class:`~mirrorlab.core.runtime.DeviceRuntime` (``runtime.py``): instruments, simulators, the
  simulated world, controllers, acquisition, recording, connect / disconnect, stop, snapshot;
  the session lock;
* :class:`~mirrorlab.core.store.session_file.SessionFile` (``store/``): the file; result groups,
  provenance and ``/config``, SWMR switching, ``write_group``, ``/log``, and the read API
  (:class:`~mirrorlab.core.store.reader.Reader`: datasets, attributes, tree, results, truth,
  streams). Only the store touches h5py;
* :class:`~mirrorlab.core.compute.Compute` (``compute.py``): ``run``, references, the executor.
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .algorithms import Algorithm, AlgorithmExecutor, ResultRef
from .compute import Compute
from .controller_runtime import ControllerRunner
from .controllers import Controller
from .devices import Instrument, SimulatedWorld, SimulatorServer
from .registry import Registry, get_registry
from .runtime import SIMULATOR_OPTIONS, DeviceRuntime
from .snapshot import SessionSnapshot
from .store.reader import Node, ResultData, StreamData
from .store.session_file import SessionFile
from .streams import Subscription

__all__ = ["SIMULATOR_OPTIONS", "Node", "ResultData", "Session", "StreamData"]


class Session:
    """One session file. Use :meth:`create` or :meth:`open`, as context managers."""

    def __init__(self, store: SessionFile, registry: Registry) -> None:
        self.registry = registry
        self._store = store
        self._runtime = DeviceRuntime(store, registry, self._notify)
        self._compute = Compute(self, store, self._runtime, self._notify)
        self.path: Path = store.path
        self.writable: bool = store.writable
        self.crashed: bool = store.crashed
        #: What was done to open the file (``""``: nothing), e.g. the open flags a killed process left cleared.
        self.recovered: str = store.recovered
        self.clock = store.clock
        self.events = store.events
        self.router = self._runtime.router
        self.instruments: dict[str, Instrument] = self._runtime.instruments
        self.controllers: dict[str, ControllerRunner] = self._runtime.controllers
        self._notify("mirrorlab_session_opened")

    def _notify(self, hook: str, **kwargs: Any) -> None:
        """Call a lifecycle hook with this session; a plugin that fails is a ``plugin_error`` warning."""
        for message in self.registry.notify(hook, session=self, **kwargs):
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
        registry = registry or get_registry()
        # every installed plugin; one not imported yet (see Registry) is listed with what it declares
        plugins = {name: {"source": p.source, "distribution": p.distribution, "version": p.version, "ok": p.ok,
                          "provides": p.provides if p.loaded else p.declared} for name, p in registry.installed().items()}
        store = SessionFile.create(Path(path), operator=operator, description=description, recipe=recipe or {},
                                   plugins=plugins, overwrite=overwrite)
        return cls(store, registry)

    @classmethod
    def open(cls, path: str | Path, writable: bool = False, registry: Registry | None = None) -> Session:
        """Open an existing session, read-only unless ``writable``.

        A file left open by a process killed while recording or running an algorithm (SWMR mode)
        opens read-only through SWMR with ``crashed = True``; a recording that did not finish must be
        closed (``mirrorlab session close FILE --aborted``) before it is opened ``writable``. A file
        left flagged open by a process killed at any other moment has its flags cleared in place
        first (``recovered`` says so); everything that process had flushed is kept. A file that a
        live process writes raises :class:`SessionError` naming that process.
        """
        registry = registry or get_registry()
        return cls(SessionFile.open(Path(path), writable), registry)

    def __enter__(self) -> Session:
        return self

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> None:
        # An exception while *recording* a new session aborts it; analysis of an existing
        # session keeps that session's status whatever happens.
        self.close("aborted" if exc_type is not None and self._store.created else None)

    # -- what it is --------------------------------------------------------------------------------
    @property
    def status(self) -> str:
        return self._store.status

    @property
    def session_id(self) -> str:
        return self._store.session_id

    @property
    def attrs(self) -> dict[str, Any]:
        """The root attributes (schema, id, status, clock origin, operator...)."""
        return self._store.attrs

    @property
    def world(self) -> SimulatedWorld | None:
        """The simulated world this session's simulators share (:meth:`set_world`); ``None``: each its own."""
        return self._runtime.world

    @property
    def recorded_seconds(self) -> float:
        """How long the last recording lasted (start to stop of the instruments), s."""
        return self._runtime.recorded_seconds

    @property
    def executor(self) -> AlgorithmExecutor | None:
        """What computes :meth:`run` (``None``: this process); see
        :attr:`Compute.executor <mirrorlab.core.compute.Compute.executor>`."""
        return self._compute.executor

    @executor.setter
    def executor(self, executor: AlgorithmExecutor | None) -> None:
        self._compute.executor = executor

    # -- devices (DeviceRuntime) ---------------------------------------------------------------------
    def add_instrument(self, label: str, plugin: str, *, port: str | None = None,
                       settings: Mapping[str, Any] | None = None, simulate: bool = False,
                       simulator: Mapping[str, Any] | None = None, timeout: float = 2.0,
                       reconnect: float | None = 60.0) -> Instrument:
        """Create, connect, identify and configure an instrument and describe it in the file
        (parameters: :meth:`DeviceRuntime.add_instrument <mirrorlab.core.runtime.DeviceRuntime.add_instrument>`)."""
        return self._runtime.add_instrument(label, plugin, port=port, settings=settings, simulate=simulate,
                                            simulator=simulator, timeout=timeout, reconnect=reconnect)

    def disconnect_instrument(self, label: str) -> None:
        """Stop instrument ``label`` (its controllers first) and release its device, under the session lock;
        refused while it is recorded."""
        self._runtime.disconnect_instrument(label)

    def connect_instrument(self, label: str) -> None:
        """Connect a disconnected instrument again (open, identify, apply its settings), under the session lock."""
        self._runtime.connect_instrument(label)

    def set_world(self, settings: Mapping[str, Any]) -> SimulatedWorld:
        """Give this session one simulated world, shared by the simulators added after this call
        (see :meth:`DeviceRuntime.set_world <mirrorlab.core.runtime.DeviceRuntime.set_world>`)."""
        return self._runtime.set_world(settings)

    def simulator(self, label: str) -> SimulatorServer:
        """The simulator serving instrument ``label`` (for fault injection in tests and demos)."""
        return self._runtime.simulator(label)

    def subscribe(self, source: str, stream: str, max_bytes: int = 64 << 20) -> Subscription:
        """Live view of a stream of an instrument or controller, independent of the file, holding at
        most ``max_bytes`` of unread blocks; released by its ``close()``, its ``with`` block or the session's close."""
        return self._runtime.subscribe(source, stream, max_bytes)

    def add_controller(self, label: str, plugin: str | type[Controller], *,
                       settings: Mapping[str, Any] | None = None, inputs: Mapping[str, str] | None = None,
                       instruments: Mapping[str, str] | None = None) -> ControllerRunner:
        """Add a controller bound to streams and instruments of this session
        (parameters: :meth:`DeviceRuntime.add_controller <mirrorlab.core.runtime.DeviceRuntime.add_controller>`)."""
        return self._runtime.add_controller(label, plugin, settings=settings, inputs=inputs, instruments=instruments)

    @property
    def acquiring(self) -> bool:
        return self._runtime.acquiring

    def start_acquisition(self, instruments: Sequence[str] | None = None) -> None:
        """Start ``instruments`` (default: all) streaming to subscribers and controllers, without writing anything."""
        self._runtime.start_acquisition(instruments)

    def stop_acquisition(self, instruments: Sequence[str] | None = None) -> None:
        """Stop acquiring (all instruments, or ``instruments``); a recording ends once none of its instruments acquires."""
        self._runtime.stop_acquisition(instruments)

    @property
    def recording(self) -> bool:
        return self._runtime.recording

    def start_recording(self, instruments: Sequence[str] | None = None) -> None:
        """Declare the streams in the file, switch to SWMR and record ``instruments`` (default: all)."""
        self._runtime.start_recording(instruments)

    def stop_recording(self) -> dict[str, dict[str, int]]:
        """Write what is queued, leave SWMR; acquisition goes on. Returns per-stream statistics:
        ``{"<source>/<stream>": {"samples": written, "dropped": dropped}}`` of this recording."""
        return self._runtime.stop_recording()

    def record(self, seconds: float | None = None,
               instruments: Sequence[str] | None = None) -> dict[str, dict[str, int]]:
        """Record ``seconds`` (``None`` or 0: until the sources end), then stop; returns per-stream
        statistics (see :meth:`DeviceRuntime.record <mirrorlab.core.runtime.DeviceRuntime.record>`)."""
        return self._runtime.record(seconds, instruments)

    def preview(self, seconds: float | None = None, instruments: Sequence[str] | None = None) -> None:
        """Acquire without recording (to align, focus, check a loop) for ``seconds``, then stop what it started."""
        self._runtime.preview(seconds, instruments)

    def operation(self) -> contextlib.AbstractContextManager[None]:
        """Mark long work (a recording, a recipe, an algorithm run) that :meth:`request_stop` ends."""
        return self._runtime.operation()

    def request_stop(self) -> None:
        """Ask the running recording, recipe step or algorithm run to end (from any thread); returns at once."""
        self._runtime.request_stop()

    @property
    def stop_requested(self) -> bool:
        return self._runtime.cancel.is_set()

    def snapshot(self) -> SessionSnapshot:
        """An immutable summary of the live session; never calls a device or the file (≥ 50 Hz safe)."""
        return self._runtime.snapshot()

    # -- algorithms (Compute) ----------------------------------------------------------------------
    def run(self, algorithm: str | type[Algorithm], inputs: Mapping[str, str | np.ndarray],
            parameters: Mapping[str, Any] | None = None,
            progress: Callable[[float, float | None, str], None] | None = None, *,
            label: str | None = None, input_units: Mapping[str, str] | None = None) -> ResultRef:
        """Run an algorithm and store its result with provenance as ``/results/<algorithm>/<run-id>``
        (parameters: :meth:`Compute.run <mirrorlab.core.compute.Compute.run>`)."""
        return self._compute.run(algorithm, inputs, parameters, progress, label=label, input_units=input_units)

    def resolve(self, reference: str, key: str = "dataset") -> str:
        """The dataset path a reference names: ``/absolute/path`` itself, ``@name/output`` the output of
        the run labelled ``name``, else of the latest successful run of the algorithm ``name``."""
        return self._compute.resolve(reference, key)

    # -- the file (SessionFile) --------------------------------------------------------------------
    def write_group(self, path: str, arrays: Mapping[str, Any], attrs: Mapping[str, Any] | None = None) -> None:
        """Write arrays into a new group (e.g. ``calibration/cam`` or ``truth/markers``), never overwritten."""
        self._store.write_group(path, arrays, attrs)

    def shared_for_reading(self, required: bool = True) -> contextlib.AbstractContextManager[None]:
        """Let other processes read the file (SWMR) during the block
        (see :meth:`SessionFile.shared_for_reading <mirrorlab.core.store.session_file.SessionFile.shared_for_reading>`)."""
        return self._store.shared_for_reading(required)

    def exists(self, path: str) -> bool:
        """Whether the file holds a group or dataset at ``path`` (``/truth/cam``)."""
        return self._store.exists(path)

    def node(self, path: str) -> Node:
        """What is at ``path``: group or dataset, shape, dtype, unit, attribute names."""
        return self._store.node(path)

    def members(self, path: str = "/") -> list[str]:
        """The names of the members of the group at ``path`` (none if ``path`` is no group)."""
        return self._store.members(path)

    def tree(self, path: str = "/") -> list[Node]:
        """Every group and dataset under the group at ``path``, parents before children."""
        return self._store.tree(path)

    def read(self, path: str, index: Any = ()) -> Any:
        """The values of the dataset at ``path`` (``index``: a part, e.g. frame ``5`` or ``slice(0, 10)``)."""
        return self._store.read(path, index)

    def read_group(self, path: str) -> dict[str, Any]:
        """Every dataset under the group at ``path``, read, by its path relative to it."""
        return self._store.read_group(path)

    def truth(self, name: str) -> dict[str, Any]:
        """The ground truth a simulator wrote under ``/truth/<name>`` (:meth:`read_group` of it)."""
        return self._store.truth(name)

    def attributes(self, path: str = "/") -> dict[str, Any]:
        """The attributes of the group or dataset at ``path`` (text decoded; JSON text: :meth:`json_attribute`)."""
        return self._store.attributes(path)

    def json_attribute(self, path: str, name: str, default: Any = None) -> Any:
        """Attribute ``name`` of ``path`` decoded from JSON (settings, labels, provenance), or ``default``."""
        return self._store.json_attribute(path, name, default)

    def stream(self, source: str, stream: str) -> StreamData:
        """A recorded stream of an instrument or a controller (times in session seconds); usable as
        ``times, data = ...``."""
        return self._store.stream(source, stream)

    def results(self, algorithm: str | None = None) -> list[ResultRef]:
        """Stored runs, oldest first (of one algorithm, or all); a run without status is ``incomplete``."""
        return self._store.results(algorithm)

    def result(self, ref: ResultRef | str) -> ResultData:
        """Read one stored run (by :class:`ResultRef` or path ``/results/<alg>/<run-id>``)."""
        return self._store.result(ref)

    def describe(self) -> dict[str, Any]:
        """JSON-ready summary: attributes, instruments and controllers with their streams, results, log size."""
        return self._store.describe()

    def log(self) -> list[dict[str, Any]]:
        """The stored structured events."""
        return self._store.log()

    # -- closing ---------------------------------------------------------------------------------
    def close(self, status: str | None = None, reason: str = "") -> None:
        """Stop recording and acquisition, close instruments and simulators, set ``status``, close the file.

        ``status`` defaults to ``closed`` for a session created here and to its stored status for
        an opened one (analysis never turns an aborted recording into a closed one). ``reason``
        (e.g. ``"interrupted (Ctrl-C) during step 2"``) is logged with the closing event. A new
        session closed ``aborted`` before it held anything is deleted (see :meth:`create`).
        """
        store = self._store
        with self._runtime.lock:
            if store.closed:
                return
            if status is None:
                status = "closed" if store.created else self.status
            if self.writable and status not in ("closed", "aborted"):
                raise ValueError("status must be 'closed' or 'aborted'")
            try:
                error = self._runtime.shut_down()
                if error is not None:
                    status = "aborted"
                if self.writable:
                    self._notify("mirrorlab_session_closing", status=status)
                    self.events.emit("info", "session", "closed", f"session {status}" + (f": {reason}" if reason else ""),
                                     **({"reason": reason} if reason else {}))
                    store.finish(status)
            finally:
                store.close()
            if error is not None:
                raise error
