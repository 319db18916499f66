"""What the console knows about its session, kept apart from any widget.

:class:`Console` owns one :class:`~mirrorlab.core.session.Session` and reads it only through the
public runtime API: ``snapshot()`` for states and counters, ``subscribe()`` for live values,
``events.subscribe`` for the log, ``start_acquisition`` / ``start_recording`` / ``stop_recording`` /
``stop_acquisition`` / ``connect_instrument`` / ``disconnect_instrument`` / ``request_stop`` / ``close``
for the operator's actions, and the session's read API for what its file holds. It names no
instrument or plugin: whatever a recipe connects appears by itself. Widgets call :meth:`poll`
from a timer (never blocking: it drains bounded subscriptions and takes a snapshot); the actions
that wait on devices or the disk run in worker threads.

Units: session seconds, each stream's declared unit, bytes.
"""

from __future__ import annotations

import contextlib
import threading
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..algorithms import ResultRef
from ..devices import SetStatus
from ..errors import MirrorlabError, SessionError
from ..events import Event
from ..recipes import Recipe, StepPlan, add_devices, check_on_session, check_outputs, load_recipe, recipe_record, run_steps
from ..session import Session
from ..snapshot import SessionSnapshot
from ..streams import StreamSpec, Subscription

#: The recipes that come with mirrorlab (package data of ``mirrorlab.sessions``).
BUNDLED = resources.files("mirrorlab.sessions")
#: Samples of each scalar stream kept for sparklines and live plots.
HISTORY = 600
#: Bytes of unread blocks a live view may hold per stream (a camera frame is ~0.2 MB).
LIVE_BYTES = 4 << 20
#: Log events kept for the log tail.
LOG_EVENTS = 500


@dataclass
class LiveStream:
    """The live view of one stream: its declaration, the newest block and recent scalar samples."""

    source: str
    spec: StreamSpec
    subscription: Subscription
    times: deque[float] = field(default_factory=lambda: deque(maxlen=HISTORY))
    values: deque[float] = field(default_factory=lambda: deque(maxlen=HISTORY))
    latest: np.ndarray | None = None  # the newest sample (any shape)
    latest_time: float | None = None

    @property
    def scalar(self) -> bool:
        return self.spec.shape == ()

    def update(self) -> None:
        """Take what arrived since the last call (never waits)."""
        for block in self.subscription.drain():
            if len(block.times) == 0:
                continue
            self.latest, self.latest_time = np.asarray(block.values[-1]), float(block.times[-1])
            if self.scalar:
                self.times.extend(float(t) for t in block.times)
                self.values.extend(float(v) for v in np.asarray(block.values, dtype=float).ravel())

    def describe_latest(self) -> str:
        """The newest value as the operator reads it: ``0.123 rad``, or the shape of an image."""
        if self.latest is None:
            return "–"
        unit = f" {self.spec.unit}" if self.spec.unit else ""
        if self.scalar:
            return f"{float(self.latest):.4g}{unit}"
        return "×".join(map(str, self.latest.shape)) + unit


class Console:
    """One session as the operator console sees it.

    Parameters
    ----------
    session
        An open session (created from a recipe, or opened for browsing).
    recipe
        The recipe it was created from (``None`` for a session file).
    """

    def __init__(self, session: Session, recipe: Recipe | None = None) -> None:
        self.session = session
        self.recipe = recipe
        self.log: deque[Event] = deque(maxlen=LOG_EVENTS)
        self.logged = 0  # events logged so far (the log keeps the last LOG_EVENTS)
        self._log_lock = threading.Lock()
        self._unsubscribe = session.events.subscribe(self._on_event)
        self.streams: dict[tuple[str, str], LiveStream] = {}
        for label, inst in session.instruments.items():
            self._watch(label, inst.streams())
        for label, runner in session.controllers.items():
            self._watch(label, runner.streams())
        self.closed = False
        #: The recipe step running now (``None``: none), and the newest progress event.
        self.current_step: StepPlan | None = None
        self.progress: Event | None = None
        #: The algorithm running now (``None``: none).
        self.running: str | None = None
        #: Instruments the operator disconnected (:meth:`disconnect`).
        self.disconnected: set[str] = set()

    # -- opening ---------------------------------------------------------------------------------
    @classmethod
    def from_recipe(cls, path: str | Path, out: Path | None = None, overrides: list[str] | None = None,
                    overwrite: bool = False, default_root: Path | None = None,
                    allow_port_url: bool = False) -> Console:
        """A new session at ``out`` (default: ``<recipe>-<UTC time>.h5`` in ``default_root``, or in
        ``out/`` beside the recipe) with the recipe's
        instruments connected and controllers bound, nothing acquiring or recorded.

        Raises :class:`~mirrorlab.core.errors.ValidationError` (file, key, problem) for an invalid
        recipe, or one that writes outside its folders (:func:`~mirrorlab.core.recipes.check_outputs`),
        before anything starts; a device that will not connect leaves no file. ``allow_port_url``: as
        ``--allow-port-url``.
        """
        recipe = load_recipe(path, overrides or [], allow_port_url=allow_port_url)
        out = out or recipe.default_output(default_root)
        check_outputs(recipe, out, overwrite)
        session = Session.create(out, operator=recipe.operator,
                                 description=recipe.description, recipe=recipe_record(recipe), overwrite=overwrite)
        try:
            add_devices(session, recipe)
        except BaseException:
            session.close("aborted")
            raise
        return cls(session, recipe)

    @classmethod
    def from_file(cls, path: str | Path) -> Console:
        """An existing session file, for browsing and analysis. It is open read-only, and for writing
        only while an analysis runs (:meth:`writable`): a terminal closed meanwhile never leaves the
        file open for writing."""
        return cls(Session.open(path))

    @contextlib.contextmanager
    def writable(self) -> Iterator[Session]:
        """The session open for writing during the block (a session file opened for browsing is
        closed and opened again writable, then read-only again after)."""
        if self.session.writable:
            yield self.session
            return
        path, registry = self.session.path, self.session.registry
        self._reopen(lambda: Session.open(path, writable=True, registry=registry),
                     lambda: Session.open(path, registry=registry))
        try:
            yield self.session
        finally:
            self._reopen(lambda: Session.open(path, registry=registry))

    def _reopen(self, *openers: Callable[[], Session]) -> None:
        """Close the session and open it with the first opener that works (the error of the first
        is raised once one of the others has opened it)."""
        self._unsubscribe()
        self.session.close()
        error: BaseException | None = None
        for opener in openers:
            try:
                self.session = opener()
            except MirrorlabError as exc:
                error = error or exc
                continue
            break
        self._unsubscribe = self.session.events.subscribe(self._on_event)
        if error is not None:
            raise error

    def _watch(self, source: str, specs: list[StreamSpec]) -> None:
        for spec in specs:
            sub = self.session.subscribe(source, spec.name, max_bytes=LIVE_BYTES)
            self.streams[(source, spec.name)] = LiveStream(source, spec, sub)

    def _on_event(self, event: Event) -> None:
        if event.kind == "progress":
            self.progress = event
        else:  # called in the publishing thread
            with self._log_lock:
                self.log.append(event)
                self.logged += 1

    def events_since(self, seen: int) -> tuple[list[Event], int]:
        """Events logged after the first ``seen`` (at most the last :data:`LOG_EVENTS`), and the new count."""
        with self._log_lock:
            new = min(self.logged - seen, len(self.log))
            return list(self.log)[len(self.log) - new:], self.logged

    # -- reading ---------------------------------------------------------------------------------
    @property
    def live(self) -> bool:
        """Whether the session has devices (a recipe) rather than only a file to browse."""
        return bool(self.session.instruments)

    @property
    def sources(self) -> list[str]:
        """Instrument labels, then controller labels, in the order they were added."""
        return [*self.session.instruments, *self.session.controllers]

    def poll(self) -> SessionSnapshot:
        """Take new live samples and a snapshot; never waits on a device or the file."""
        for live in self.streams.values():
            live.update()
        return self.session.snapshot()

    def source_streams(self, source: str) -> list[LiveStream]:
        return [live for (label, _), live in self.streams.items() if label == source]

    def identity(self, source: str) -> str:
        """One line saying what a source is: plugin, vendor, model, serial number, firmware."""
        inst = self.session.instruments.get(source)
        if inst is None:
            runner = self.session.controllers[source]
            inputs = ", ".join(f"{role}={label}/{stream}" for role, (label, stream) in runner.inputs.items())
            commands = ", ".join(f"{role}={i.label}" for role, i in runner.instruments.items())
            return f"controller {runner.controller.name}: inputs {inputs or 'none'}; commands {commands or 'none'}"
        ident = inst.identity
        parts = [inst.name]
        if ident is not None:
            parts += [f"{ident.vendor} {ident.model}".strip(), f"s/n {ident.serial}" if ident.serial else "",
                      f"fw {ident.firmware}" if ident.firmware else ""]
        return " · ".join(p for p in parts if p)

    # -- acting (these wait on devices or the disk: call them from a worker thread) ----------------
    @property
    def connected(self) -> list[str]:
        """The instruments not disconnected by the operator (those that preview and record)."""
        return [label for label in self.session.instruments if label not in self.disconnected]

    def preview(self) -> None:
        """Start every connected instrument acquiring (and the controllers), without recording."""
        self.session.start_acquisition(self.connected)

    def toggle_recording(self) -> bool:
        """Start recording every connected instrument, or stop the running recording; return whether recording now."""
        if self.session.recording:
            self.session.stop_recording()
            return False
        self.session.start_recording(self.connected)
        return True

    def disconnect(self, source: str) -> None:
        """Stop one instrument (and the controllers bound to it) and release its device; the others go on."""
        self.session.disconnect_instrument(source)
        self.disconnected.add(source)

    def connect(self, source: str) -> None:
        """Connect a disconnected instrument again: open, identify, apply its settings."""
        self.session.connect_instrument(source)
        self.disconnected.discard(source)

    def stop(self) -> None:
        """Stop acquiring (and the recording, written to the end)."""
        self.session.stop_acquisition()

    def run_steps(self, start: int = 0, recipe: Recipe | None = None) -> None:
        """Run the steps of ``recipe`` (default: the session's own) from index ``start`` on this
        session, until one fails or :meth:`cancel`; :attr:`current_step` says which one runs."""
        recipe = recipe or self.recipe
        if recipe is None:
            return
        try:
            with self.session.operation():
                run_steps(self.session, recipe.steps[start:], self._step_started)
        finally:
            self.current_step = None

    def analysis_recipes(self) -> list[Recipe]:
        """The bundled analysis recipes (no instruments, nothing recorded) that can run on this
        session, e.g. the demo's ``rssr_analysis.toml`` (reads the recipe files: call from a worker)."""
        found = []
        for path in sorted(BUNDLED.iterdir(), key=lambda p: p.name):
            if path.name.endswith(".toml"):
                try:
                    found.append(load_recipe(Path(str(path)), [], analysis=True))
                except MirrorlabError:  # a recipe that records: not an analysis
                    continue
        return found

    def run_recipe(self, recipe: Recipe) -> None:
        """Run an analysis recipe's steps on this session (see :meth:`run_steps`)."""
        if self.session.recording:
            raise SessionError(f"{self.session.path} is recording; stop the recording (r) before running "
                               f"{recipe.path.name}")
        self.progress, self.running = None, recipe.path.name
        try:
            with self.writable() as session:
                check_on_session(recipe, session)
                self.run_steps(0, recipe)
        finally:
            self.running = None

    def _step_started(self, step: StepPlan) -> None:
        self.progress = None
        self.current_step = step

    def cancel(self) -> None:
        """Ask the running step (or recording, or algorithm) to end cleanly; no later step runs."""
        self.session.request_stop()

    def run_algorithm(self, name: str, inputs: dict[str, str], parameters: dict[str, Any]) -> ResultRef:
        """Run a registered algorithm on datasets of the session and store its result
        (:meth:`Session.run`); :meth:`cancel` stops it at its next progress report."""
        if self.session.recording:
            raise SessionError(f"{self.session.path} is recording; stop the recording (r) before running {name}")
        self.progress, self.running = None, name
        try:
            with self.writable() as session:
                return session.run(name, inputs, parameters)
        finally:
            self.running = None

    def set_parameter(self, source: str, name: str, value: Any) -> SetStatus:
        """Send one live parameter as a set-point; returns at once, with its status (its ``wait()`` returns
        the value applied, in its unit)."""
        return self.session.instruments[source].set(name, value)

    def close(self) -> None:
        """Stop everything and close the session file cleanly (idempotent)."""
        if self.closed:
            return
        self.closed = True
        self._unsubscribe()
        self.session.close()
