"""Running a controller: its thread, its context, its supervision and its latency statistics.

The session creates one :class:`ControllerRunner` per controller. The runner subscribes to the
controller's bound input streams, calls :meth:`Controller.on_block` for every block in its own
thread, and hands the controller a :class:`ControllerContext` through which it commands its
instruments. Every acknowledged set-point is published as a sample of the stream
``<role>.<parameter>`` and its latency (acknowledgement time minus the time of the input sample
that caused it, s) as a sample of ``latency``, so the session records what the loop did.
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from enum import StrEnum
from typing import Any

import numpy as np

from .controllers import Controller
from .devices import Instrument
from .errors import DeviceError, MirrorlabError, Problem
from .streams import Emitter, StreamSpec, Subscription


class ControllerState(StrEnum):
    """Lifecycle state of a controller (:attr:`ControllerRunner.state`); a ``str`` equal to its value,
    which is what events and snapshots carry."""

    IDLE = "idle"        #: added, not started
    RUNNING = "running"  #: its thread runs
    FAILED = "failed"    #: its code raised; the instruments it commands were told to hold
    STOPPED = "stopped"  #: stopped with the session's acquisition


#: Latencies kept for the statistics of :meth:`ControllerRunner.latency_stats`.
LATENCY_WINDOW = 2048


def setpoint_stream(role: str, parameter: str) -> str:
    """Name of the stream that records the set-points of ``parameter`` sent to ``role``."""
    return f"{role}.{parameter}"


@dataclass(frozen=True)
class LatencyStats:
    """Latency from input sample to acknowledged set-point over the last commands, s."""

    count: int
    p50: float
    p99: float
    max: float


class ControllerContext:
    """What a controller's code gets: its instruments, its output streams and the session clock."""

    def __init__(self, runner: ControllerRunner) -> None:
        self._runner = runner

    @property
    def settings(self) -> Mapping[str, Any]:
        return self._runner.controller.settings

    def instrument(self, role: str) -> Instrument:
        """The instrument bound to ``role`` (for reading its settings or cached status)."""
        return self._runner.instruments[role]

    def now(self) -> float:
        """Session time, s."""
        return self._runner.emitter.now()

    def set(self, role: str, parameter: str, value: Any, sample_time: float | None = None) -> Any:
        """Send a set-point to the instrument bound to ``role``, wait for its acknowledgement and record it.

        Parameters
        ----------
        role
            A commanded role of the controller (:attr:`Controller.commands`).
        parameter
            One of the live parameters the controller declared for that role.
        value
            New value in the parameter's unit.
        sample_time
            Session time (s) of the input sample this set-point answers; its latency to the
            acknowledgement is recorded in ``latency``.

        Returns the value the instrument applied (``Instrument.set(...).wait()``, in the controller's
        thread). A device error is reported as a ``setpoint_failed`` warning and re-raised; the
        controller may go on.
        """
        return self._runner.set(role, parameter, value, sample_time)

    def send(self, role: str, parameter: str, value: Any, sample_time: float | None = None) -> None:
        """Like :meth:`set`, but return at once: a sender thread of the controller sends it.

        For a loop whose inputs come faster than the device acknowledges: only the newest value
        of each ``role.parameter`` waits to be sent, and one still waiting when a newer one comes
        is dropped (counted as *superseded* in :meth:`Session.snapshot`); what was sent and
        acknowledged is recorded as with :meth:`set`, with its latency. A device error is
        reported as a ``setpoint_failed`` warning; the next value is sent all the same. Values
        still waiting when the controller stops are not sent.
        """
        self._runner.send(role, parameter, value, sample_time)

    def emit(self, stream: str, times: Any, values: Any) -> None:
        """Publish samples of a stream the controller declared in :meth:`Controller.streams`."""
        self._runner.emitter(stream, times, values)


class ControllerRunner:
    """Runs one controller in a supervised thread (created by the session).

    Parameters
    ----------
    controller
        The controller instance.
    inputs
        Role -> ``(instrument label, stream)`` it subscribes to.
    instruments
        Role -> the commanded :class:`Instrument`.
    emitter
        Publishes the controller's streams under its label.
    subscribe
        ``subscribe(keys)`` -> :class:`Subscription` (the session's router).
    report
        ``report(level, kind, message, **data)`` into the session's events.
    """

    def __init__(self, controller: Controller, inputs: Mapping[str, tuple[str, str]],
                 instruments: Mapping[str, Instrument], emitter: Emitter,
                 subscribe: Callable[[list[tuple[str, str]]], Subscription],
                 report: Callable[..., None]) -> None:
        self.controller = controller
        self.label = controller.label
        self.inputs = dict(inputs)
        self.instruments = dict(instruments)
        self.emitter = emitter
        self.report = report
        self.state = ControllerState.IDLE
        self.error: BaseException | None = None
        self.commands_sent = 0
        self.commands_failed = 0
        self._roles = {key: role for role, key in self.inputs.items()}
        self._subscribe = subscribe
        self._subscription: Subscription | None = None
        self._latencies: deque[float] = deque(maxlen=LATENCY_WINDOW)
        self._latency_lock = threading.Lock()  # appended by the loop, read by snapshot()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.commands_superseded = 0
        # send(): the newest value per (role, parameter) not yet sent, and the thread that sends them
        self._outbox: dict[tuple[str, str], tuple[Any, float | None]] = {}
        self._outbox_ready = threading.Condition()
        self._sender: threading.Thread | None = None

    # -- declarations ---------------------------------------------------------------------------
    def streams(self) -> list[StreamSpec]:
        """Set-point streams, ``latency`` and the controller's own streams."""
        specs = [StreamSpec("latency", "f8", (), "s", None,
                            "input sample to acknowledged set-point, s (one sample per command)")]
        for role, names in self.controller.commanded().items():
            inst = self.instruments[role]
            for name in names:
                p = inst.parameters[name]
                specs.append(StreamSpec(setpoint_stream(role, name), "f8", tuple(getattr(p, "shape", ()) or ()),
                                        p.unit, None, f"set-points sent to {inst.label}.{name}"))
        return specs + list(self.controller.streams())

    # -- lifecycle ------------------------------------------------------------------------------
    def start(self) -> None:
        """Subscribe to the inputs and start the thread."""
        self._stop.clear()
        self.error = None
        self._subscription = self._subscribe(list(self.inputs.values()))
        self._thread = threading.Thread(target=self._run, name=f"controller {self.label}", daemon=True)
        self._set_state(ControllerState.RUNNING)
        self._thread.start()

    def stop(self, timeout: float = 2.0) -> None:
        """Stop the thread (after its current block) and release the subscription (idempotent).

        A controller that takes every block in order (``latest_only = False``, a filter) first works
        through the blocks already waiting, for up to half of ``timeout``; the input samples it never
        processed (it fell behind, e.g. under load) are reported in one ``inputs_unprocessed`` warning.
        """
        thread, sub = self._thread, self._subscription
        running = thread is not None and thread.is_alive() and thread is not threading.current_thread()
        if running and thread is not None and sub is not None and not self.controller.latest_only:
            deadline = time.monotonic() + timeout / 2
            while sub.nbytes and thread.is_alive() and time.monotonic() < deadline:
                time.sleep(0.005)
        self._stop.set()
        if sub is not None:
            sub.close()  # wakes a waiting get()
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
            if thread.is_alive():
                self.report("error", "stop_timeout", f"controller {self.label!r} did not stop within {timeout:g} s "
                            "(its on_block does not return); the session goes on without it")
        if thread is not None and sub is not None and sub.discarded and not self.controller.latest_only \
                and self.state != ControllerState.FAILED:  # a failure is its own error
            self.report("warning", "inputs_unprocessed", f"controller {self.label!r} fell behind its input: "
                        f"{sub.discarded} input sample{'s' if sub.discarded != 1 else ''} got no output (the "
                        "computer did not keep up with the input rate)", samples=sub.discarded)
        self._thread = None
        with self._outbox_ready:
            self._outbox.clear()  # not sent: the instruments keep the last acknowledged value
            self._outbox_ready.notify()
            sender, self._sender = self._sender, None
        if sender is not None:  # ends after the command it may be waiting for
            sender.join(timeout)
        if self.state == ControllerState.RUNNING:
            self._set_state(ControllerState.STOPPED)

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def _set_state(self, state: ControllerState) -> None:
        self.state = state
        self.report("info", "state", f"controller {self.label!r} is {state}", state=state.value)  # the cause is its own event

    def _run(self) -> None:
        ctx = ControllerContext(self)
        sub = self._subscription
        assert sub is not None
        try:
            self.controller.setup(ctx)
            while not self._stop.is_set():
                block = sub.get(timeout=0.5)
                if block is None:
                    continue
                blocks = [block, *sub.drain()] if self.controller.latest_only else [block]
                if self.controller.latest_only:  # the newest block of each input, in arrival order
                    blocks = list({(b.instrument, b.stream): b for b in blocks}.values())
                for b in blocks:
                    self.controller.on_block(self._roles[(b.instrument, b.stream)], b, ctx)
            self.controller.teardown(ctx)
        except Exception as exc:  # supervised: report, hold the instruments, end the thread
            self._fail(exc)

    def _fail(self, exc: BaseException) -> None:
        self.error = exc
        kind = "" if isinstance(exc, MirrorlabError) else f"{type(exc).__name__}: "
        self.report("error", "controller_failed", f"controller {self.label!r} failed: {kind}{exc}; "
                    f"told {', '.join(i.label for i in self.instruments.values()) or 'nothing'} to hold")
        for inst in self.instruments.values():
            try:
                inst.hold()
            except (MirrorlabError, OSError) as hold_error:
                self.report("error", "hold_failed", f"{inst.device_name} could not be told to hold: {hold_error}")
        self._set_state(ControllerState.FAILED)

    # -- commands -------------------------------------------------------------------------------
    def _check_declared(self, role: str, parameter: str) -> None:
        if parameter not in self.controller.commanded().get(role, ()):
            known = [f"{r}.{n}" for r, names in self.controller.commanded().items() for n in names]
            raise MirrorlabError(f"controller {self.label!r} did not declare {role}.{parameter} in `commands` "
                                 f"(declared: {', '.join(known) or 'none'})")

    def send(self, role: str, parameter: str, value: Any, sample_time: float | None) -> None:
        self._check_declared(role, parameter)
        with self._outbox_ready:
            if self._outbox.pop((role, parameter), None) is not None:
                self.commands_superseded += 1
            self._outbox[(role, parameter)] = (value, sample_time)  # last in the dict: sent after older ones
            self._outbox_ready.notify()
            if self._sender is None:
                self._sender = threading.Thread(target=self._send_loop, name=f"controller {self.label} sender",
                                                daemon=True)
                self._sender.start()

    def _send_loop(self) -> None:
        while True:
            with self._outbox_ready:
                while not self._outbox and not self._stop.is_set():
                    self._outbox_ready.wait()
                if self._stop.is_set() or self._sender is not threading.current_thread():
                    return  # stopped (a sender stop() gave up on is not the one a restart starts)
                key = next(iter(self._outbox))  # the oldest waiting
                value, sample_time = self._outbox.pop(key)
            try:
                self._apply(*key, value, sample_time)
            except Exception as exc:  # a device error is already reported; anything else is, here
                if not isinstance(exc, DeviceError):
                    self.commands_failed += 1
                    self.report("warning", "setpoint_failed", f"controller {self.label!r}: {key[0]}.{key[1]} = "
                                f"{value}: {type(exc).__name__}: {exc}")

    def set(self, role: str, parameter: str, value: Any, sample_time: float | None) -> Any:
        self._check_declared(role, parameter)
        return self._apply(role, parameter, value, sample_time)

    def _apply(self, role: str, parameter: str, value: Any, sample_time: float | None) -> Any:
        inst = self.instruments[role]
        try:
            applied = inst.set(parameter, value).wait()  # the latency runs to the acknowledgement
        except DeviceError as exc:
            self.commands_failed += 1
            self.report("warning", "setpoint_failed", f"controller {self.label!r}: {inst.device_name} "
                        f"did not take {parameter} = {value}: {exc}")
            raise
        ack = self.emitter.now()
        self.commands_sent += 1
        self.emitter(setpoint_stream(role, parameter), [ack], np.asarray(applied, dtype="f8")[None])
        if sample_time is not None:
            latency = ack - sample_time
            with self._latency_lock:
                self._latencies.append(latency)
            self.emitter("latency", [ack], [latency])
        return applied

    def latency_stats(self) -> LatencyStats | None:
        """p50 / p99 / max of the recent latencies (``None`` before the first command)."""
        with self._latency_lock:
            values = np.array(self._latencies)
        if values.size == 0:
            return None
        p50, p99 = np.percentile(values, [50, 99])
        return LatencyStats(int(values.size), float(p50), float(p99), float(values.max()))


def bind(controller: Controller, where: str, inputs: Mapping[str, str], instruments: Mapping[str, str],
         available: Mapping[str, Instrument]) -> tuple[dict[str, tuple[str, str]], dict[str, Instrument], list[Problem]]:
    """Check a controller's bindings against its declared roles and the session's instruments.

    Parameters
    ----------
    controller
        The controller, its settings validated.
    where
        Key prefix of the problems (``controllers.<label>``).
    inputs, instruments
        Input role -> ``"<instrument>/<stream>"``; commanded role -> instrument label.
    available
        The session's instruments by label.

    Returns the bound inputs (role -> ``(label, stream)``), the bound instruments (role ->
    instrument) and every problem found.
    """
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
        inst = available.get(label)
        streams = [s.name for s in inst.streams()] if inst is not None else []
        if inst is None or stream not in streams:
            problems.append(Problem(f"{where}.inputs.{role}", f"{ref!r} is no stream of this session; " + (
                f"{label} has: {', '.join(streams)}" if inst is not None else
                f"instruments: {', '.join(available) or 'none'}")))
            continue
        bound_inputs[role] = (label, stream)
    for role in set(instruments) - set(commanded):
        problems.append(Problem(f"{where}.instruments.{role}", f"{cls.name} commands no {role!r}; "
                                f"it commands: {', '.join(commanded) or 'nothing'}"))
    for role, names in commanded.items():
        chosen = instruments.get(role)
        inst = available.get(str(chosen))
        if inst is None:
            problems.append(Problem(f"{where}.instruments.{role}", f"required: the label of an instrument "
                                    f"of this session ({', '.join(available) or 'none'})"
                                    + (f"; {chosen!r} is not one" if chosen is not None else "")))
            continue
        not_live = [n for n in names if n not in inst.parameters or not inst.parameters[n].live]
        if not_live:
            problems.append(Problem(f"{where}.instruments.{role}", f"{inst.name} {chosen!r} has no live-settable "
                                    f"{', '.join(not_live)}, which {cls.name} sets"))
            continue
        bound_instruments[role] = inst
    return bound_inputs, bound_instruments, problems
