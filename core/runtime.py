"""The device runtime of a session: its live instruments, simulators, world and controllers.

:class:`DeviceRuntime` connects instruments (starting a simulator for a simulated one), binds
controllers, starts and stops acquisition, records (the :class:`~mirrorlab.core.store.session_file.SessionFile`
switches the file to SWMR mode and its recorder writes what the router queues), and takes the
:class:`~mirrorlab.core.snapshot.SessionSnapshot` a UI polls. One lock (:attr:`DeviceRuntime.lock`)
serialises every change of state (instruments, acquisition, recording, closing), so a UI thread
and a script thread never race; :meth:`~DeviceRuntime.snapshot` takes none. Long work (a recording,
a recipe, an algorithm run) is an :meth:`~DeviceRuntime.operation` that
:meth:`~DeviceRuntime.request_stop` ends.

:class:`~mirrorlab.core.session.Session` is its public face; the methods' parameters are documented here.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from types import MappingProxyType
from typing import Any

from .controller_runtime import ControllerRunner, bind
from .controllers import Controller
from .devices import Instrument, SerialInstrument, SimulatedWorld, SimulatorServer
from .errors import Problem, SessionError, ValidationError
from .params import Parameter, ParameterSet, identifier_problem
from .registry import Registry
from .snapshot import ControllerSnapshot, InstrumentSnapshot, RecorderSnapshot, SessionSnapshot
from .store.recorder import Recorder
from .store.session_file import SessionFile
from .streams import Emitter, StreamRouter, Subscription

SIMULATOR_OPTIONS = ParameterSet(
    Parameter("seed", int, 0, bounds=(0, None), help="seed of the simulator's random generator"),
    Parameter("clock", str, "REAL", choices=("REAL", "FAST"),
              help="REAL: modelled timing in real time; FAST: as fast as possible"),
    Parameter("transport", str, "pty", choices=("pty", "tcp"), help="byte stream the driver talks through"),
)

#: Calls a lifecycle hook with the session: ``notify("mirrorlab_recording_started")``, keywords passed on.
Notify = Callable[..., None]


class DeviceRuntime:
    """The live side of a session whose file is ``store``: plugins from ``registry``; ``notify`` calls
    the lifecycle hooks (recording started and stopped)."""

    def __init__(self, store: SessionFile, registry: Registry, notify: Notify) -> None:
        self.store = store
        self.registry = registry
        self.notify = notify
        self.events = store.events
        self.clock = store.clock
        self.router = StreamRouter(on_overflow=self._on_overflow)
        self.instruments: dict[str, Instrument] = {}
        self.controllers: dict[str, ControllerRunner] = {}
        self._simulators: dict[str, SimulatorServer] = {}
        #: The simulated world this session's simulators share (:meth:`set_world`); ``None``: each its own.
        self.world: SimulatedWorld | None = None
        #: One lock for every change of state; snapshot() takes none.
        self.lock = threading.RLock()
        #: Set by request_stop(): algorithm runs (and record) end cooperatively at their next check.
        self.cancel = threading.Event()
        self._operations = 0
        self._acquiring: set[str] = set()
        self._last_recorder: Recorder | None = None
        self._recording: list[str] = []
        self._recorded_controllers: list[str] = []
        self._reconnects_at_start: dict[str, int] = {}
        self._recorded_streams: list[tuple[str, str]] = []
        #: How long the last recording lasted (start to stop of the instruments), s.
        self.recorded_seconds = 0.0
        self._record_start = 0.0

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
            Instrument settings (validated against the plugin's parameters).
        simulate
            Start the plugin's simulator on a pty (or TCP) and connect to it instead of a
            real driver.
        simulator
            Simulator options: ``seed``, ``clock`` (``REAL``/``FAST``), ``transport`` (``pty``/``tcp``).
        timeout
            Seconds allowed for each device call.
        reconnect
            Reconnect budget: seconds of attempts after a lost connection before the instrument is
            ``failed`` (``None``: keep trying; 0: never reconnect).
        """
        _require_label(label, "instrument")
        with self.lock:
            self.store.require_writable("add an instrument")
            if label in self.instruments or self.store.exists(f"instruments/{label}"):
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
            self.store.write_instrument(label, instrument.metadata(), simulate, instrument.settings,
                                        sim_options if served else None)
            self.events.emit("info", label, "instrument_added",
                             f"{plugin} {label!r} ready" + (" (simulated)" if simulate else
                                                             f" on {instrument.port}" if instrument.port else ""))
            return instrument

    def _instrument(self, label: str) -> Instrument:
        try:
            return self.instruments[label]
        except KeyError:
            raise SessionError(f"no instrument {label!r} in this session; its instruments: "
                               f"{', '.join(self.instruments) or 'none'}") from None

    def disconnect_instrument(self, label: str) -> None:
        """Stop instrument ``label`` (the controllers bound to it first) and release its device; the
        others go on. Refused while a recording includes it. :meth:`connect_instrument` undoes it."""
        with self.lock:
            inst = self._instrument(label)
            if self.store.recorder is not None and label in self._recording:
                raise SessionError(f"{label} is being recorded; stop the recording before disconnecting it")
            self.stop_acquisition([label])
            inst.close()
            inst.set_state("stopped", f"{inst.device_name} disconnected by the operator")

    def connect_instrument(self, label: str) -> None:
        """Connect instrument ``label`` again (after :meth:`disconnect_instrument`): open, identify,
        apply its settings. If that fails it is left closed (``stopped``) and the error raised."""
        with self.lock:
            inst = self._instrument(label)
            inst.set_state("connecting")
            try:
                inst.reconnect()
            except BaseException:
                inst.close()
                inst.set_state("stopped", f"{inst.device_name} did not connect")
                raise
            inst.set_state("idle", f"{inst.device_name} connected")

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
        with self.lock:
            self.store.require_writable("set the simulated world")
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
        with self.lock:
            self.store.require_writable("add a controller")
            _require_label(label, "controller")
            if label in self.controllers or label in self.instruments:
                raise SessionError(f"{label!r} already names an instrument or controller of this session; "
                                   "pick another label")
            cls = self.registry.controller(plugin) if isinstance(plugin, str) else plugin
            controller = cls(label, settings)
            bound_inputs, bound_instruments, problems = bind(controller, f"controllers.{label}", dict(inputs or {}),
                                                             dict(instruments or {}), self.instruments)
            if problems:
                raise ValidationError(problems)
            runner = ControllerRunner(controller, bound_inputs, bound_instruments, Emitter(label, self.router, self.clock),
                                      self.router.subscribe, self._reporter(label))
            runner.emitter.streams = {s.name: s for s in runner.streams()}
            self.store.write_controller(label, cls, controller.settings, dict(inputs or {}), dict(instruments or {}))
            self.controllers[label] = runner
            self.events.emit("info", label, "controller_added", f"controller {cls.name} {label!r} ready")
            if self._acquiring:
                self._start_controllers()
            return runner

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
        with self.lock:
            if self.store.closed:
                raise SessionError(f"{self.store.path} is closed")
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
        with self.lock:
            labels = set(self._acquiring if instruments is None else instruments) & self._acquiring
            self._halt(labels)
            if self.store.recorder is not None and not set(self._recording) & self._acquiring:
                self.stop_recording()

    def _halt(self, labels: set[str]) -> None:
        """Stop the controllers bound to ``labels``, then those instruments (recording untouched)."""
        with self.lock:
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
        return self.store.recorder is not None

    def start_recording(self, instruments: Sequence[str] | None = None) -> None:
        """Declare the streams in the file, switch to SWMR and record ``instruments`` (default: all).

        Instruments not yet acquiring are started; those already acquiring (a preview) are not
        restarted. Controllers whose instruments are all recorded are recorded too.
        """
        with self.lock:
            self.store.require_writable("record")
            if self.store.recorder is not None:
                raise SessionError("already recording; stop_recording() first")
            labels = self._labels(instruments, "record")
            runners = [r for r in self.controllers.values() if self._bound_labels(r) <= set(labels)]
            streams = [("instruments", label, spec) for label in labels for spec in self.instruments[label].streams()]
            streams += [("controllers", r.label, spec) for r in runners for spec in r.streams()]
            self._recorded_streams = self.store.start_recording(streams, self.router)
            self._recording = labels
            self._recorded_controllers = [r.label for r in runners]
            self._reconnects_at_start = {label: inst.reconnects for label, inst in self.instruments.items()}
            self._record_start = time.monotonic()
            self.router.start_recording(labels + self._recorded_controllers)
            self.events.emit("info", "session", "recording_started", "recording started", instruments=labels,
                             controllers=self._recorded_controllers)
            self.start_acquisition(labels)
            self.notify("mirrorlab_recording_started")

    def stop_recording(self) -> dict[str, dict[str, int]]:
        """Write what is queued, leave SWMR; acquisition goes on. Returns per-stream statistics:
        ``{"<source>/<stream>": {"samples": written, "dropped": dropped}}`` of this recording."""
        with self.lock:
            if self.store.recorder is None:
                raise SessionError("not recording")
            self.router.stop_recording()
            self.recorded_seconds = time.monotonic() - self._record_start
            self._last_recorder = self.store.recorder
            self.store.stop_recording()
            stats = self._last_stats()
            self.store.write_recording_stats(
                {label: self.instruments[label].reconnects - self._reconnects_at_start[label] for label in self._recording},
                self._recorded_controllers, stats)
            dropped = sum(s["dropped"] for s in stats.values())
            self.events.emit("warning" if dropped else "info", "session", "recording_stopped",
                             f"recording stopped after {self.recorded_seconds:.1f} s: "
                             f"{sum(s['samples'] for s in stats.values())} samples written, {dropped} dropped",
                             statistics=stats, seconds=self.recorded_seconds)
            self.store.write_log()
            self.store.flush()
            self.notify("mirrorlab_recording_stopped", statistics=stats)
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
            recorder = self.store.recorder
            recorded = [self.instruments[label] for label in self._recording]
            try:
                self._wait_sources(recorded, seconds, "acquire", recorder)
            finally:
                # Instruments started for this recording stop first, so it holds all they acquired.
                self._halt({i.label for i in recorded} - was_acquiring)
                stats = self.stop_recording() if self.store.recorder is recorder else self._last_stats()
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
            if self.cancel.wait(0.1 if seconds is None else min(0.1, max(0.0, seconds - elapsed))):
                self.events.emit("info", "session", "stopped_on_request",
                                 f"{what} ended on request after {time.monotonic() - start:.1f} s")
                break
            self._report_ended(sources, ended, time.monotonic() - start, seconds)
            if recorder is not None and (self.store.recorder is not recorder or recorder.error is not None):
                break  # stopped from another thread, or the recorder failed
            if all(i.failed is not None for i in sources):
                self.events.emit("error", "session", "all_failed", "every instrument failed; stopping")
                break
            if not any(i.running for i in sources):
                break  # every source has ended
        done = time.monotonic() - start
        self.events.progress(what, done, done if seconds is None else seconds, "recording" if recorder else "previewing")

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
        with self.lock:
            if self._operations == 0:
                self.cancel.clear()
            self._operations += 1
        try:
            yield
        finally:
            with self.lock:
                self._operations -= 1

    def request_stop(self) -> None:
        """Ask the running :meth:`record`, recipe step or algorithm run to end (from any thread).

        Cooperative: the recording stops and is written, a running algorithm ends as ``cancelled``
        at its next progress report, a recipe runs no further step. Returns at once.
        """
        self.cancel.set()
        self.events.emit("info", "session", "stop_requested", "stop requested")

    def snapshot(self) -> SessionSnapshot:
        """An immutable summary of the live session; never calls a device or the file (≥ 50 Hz safe)."""
        counts = self.router.counts()
        recorder = self.store.recorder
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
        return SessionSnapshot(self.clock.now(), str(self.store.path), bool(self._acquiring), recorder is not None,
                               now - self._record_start if recorder is not None else self.recorded_seconds,
                               MappingProxyType(instruments), MappingProxyType(controllers), rec)

    # -- closing ---------------------------------------------------------------------------------
    def shut_down(self) -> BaseException | None:
        """Stop recording and acquisition, close subscriptions, instruments and simulators (under the
        lock). Returns the recording's error, if stopping it failed; everything is closed anyway."""
        error = None
        with self.lock:
            if self.store.recorder is not None:
                try:
                    self.stop_recording()
                except Exception as exc:  # keep closing: instruments, simulators, status
                    error = exc
            self.stop_acquisition()
            self.router.close_all()
            for inst in self.instruments.values():
                inst.close()
            for label in list(self._simulators):
                self._stop_simulator(label)
        return error


def _require_label(label: str, kind: str) -> None:
    """Raise :class:`ValidationError` unless ``label`` may name the group of an instrument or controller
    (``/instruments/<label>``): ``"/truth/x"`` or ``"."`` would write elsewhere in the file."""
    if reason := identifier_problem(label):
        raise ValidationError([Problem(f"{kind} label", reason)])
