"""Algorithms: pure functions of arrays with declared inputs, outputs and typed parameters.

An algorithm plugin subclasses :class:`Algorithm`. The framework reads the inputs (from a session
file, CSV files or arrays handed over by a script), validates the parameters, calls
:meth:`Algorithm.run` with a :class:`RunContext` for progress and cancellation, and stores what
it returns with its provenance. Because ``run`` sees only arrays and plain values, the same
algorithm runs from the CLI, a recipe step, the TUI, a Python script or a worker process of a
batch engine, without change.
"""

from __future__ import annotations

import re
import threading
import traceback
from abc import ABC, abstractmethod
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

import numpy as np

from .errors import AlgorithmError, AlgorithmInputError, Cancelled, Problem
from .params import ParameterSet

if TYPE_CHECKING:
    from .session import Session


@dataclass(frozen=True)
class Port:
    """One declared input or output of an algorithm.

    Attributes
    ----------
    name
        Key in the ``inputs`` / returned mapping; dataset name under the result group.
    description
        What it holds, with its shape, e.g. ``"(frames, markers, 3) marker positions"``.
    unit
        Unit of the values (``"mm"``, ``"px"``, ``"rad/s"``...).
    optional
        Inputs only: the algorithm can run without it.
    """

    name: str
    description: str = ""
    unit: str = ""
    optional: bool = False

    def describe(self) -> dict[str, Any]:
        return {"name": self.name, "description": self.description, "unit": self.unit,
                "optional": self.optional}


class RunContext:
    """Given to :meth:`Algorithm.run`: report progress, check for cancellation.

    Cancellation is cooperative: :meth:`progress` and :meth:`check` raise
    :class:`~mirrorlab.core.errors.Cancelled` once ``cancel`` is set, so an algorithm that reports
    progress inside its long loops is cancellable between two reports; :func:`execute` stores it
    as ``status = "cancelled"``.

    Parameters
    ----------
    progress
        Called as ``progress(done, total, message)``; ``None`` to ignore progress.
    cancel
        An event that, once set, makes :meth:`check` raise :class:`~mirrorlab.core.errors.Cancelled`
        (the session passes the one :meth:`Session.request_stop` sets).
    """

    def __init__(self, progress: Callable[[float, float | None, str], None] | None = None,
                 cancel: threading.Event | None = None) -> None:
        self._progress = progress
        self.cancel = cancel or threading.Event()

    def progress(self, done: float, total: float | None = None, message: str = "") -> None:
        """Report ``done`` of ``total`` units of work; also checks for cancellation (see :meth:`check`)."""
        if self._progress is not None:
            self._progress(done, total, message)
        self.check()  # after the callback: a stop it requested ends the run at once

    def check(self) -> None:
        """Raise :class:`~mirrorlab.core.errors.Cancelled` if the run was asked to stop."""
        if self.cancel.is_set():
            raise Cancelled("stopped on request")


#: Roles an algorithm may declare (:attr:`Algorithm.roles`), for screens and tools that look an
#: algorithm up by what it does rather than by its name: role -> (inputs, outputs) it must have.
#: ``marker_detector``: input ``frames`` (F, H, W) grey levels, output ``xy`` (F, K, 2) marker
#: centres, px, x right, y down, NaN-padded (the console's camera view draws them).
ROLES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "marker_detector": (("frames",), ("xy",)),
}


class Algorithm(ABC):
    """Base class of algorithm plugins.

    Subclasses declare ``name``, ``version``, ``description``, ``parameters``, ``inputs`` and
    ``outputs`` as class attributes and implement :meth:`run`.
    """

    name: ClassVar[str]
    version: ClassVar[str]
    description: ClassVar[str]
    parameters: ClassVar[ParameterSet] = ParameterSet()
    inputs: ClassVar[tuple[Port, ...]] = ()
    outputs: ClassVar[tuple[Port, ...]] = ()
    #: Inputs whose first axis is frames, each frame computed on its own: a batch engine may then
    #: run chunks of frames apart and concatenate the outputs (all frames first) in frame order.
    frame_inputs: ClassVar[tuple[str, ...]] = ()
    #: Padding of outputs that are ragged along their second axis (e.g. markers per frame) when
    #: chunks are merged: output name -> fill value; floating outputs not listed are NaN-padded.
    frame_fill: ClassVar[Mapping[str, Any]] = {}
    #: What the algorithm is, among :data:`ROLES` (e.g. ``("marker_detector",)``): the registry
    #: checks that it has each role's ports.
    roles: ClassVar[tuple[str, ...]] = ()

    @abstractmethod
    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any],
            context: RunContext) -> dict[str, Any]:
        """Compute the outputs from ``inputs`` (arrays) and validated ``params``.

        Returns a mapping of output name to array or scalar; every declared output must be
        present. Raise an :class:`~mirrorlab.core.errors.AlgorithmError` subclass naming the
        frame or marker on degenerate input.
        """

    @classmethod
    def frame_wise(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        """The inputs that may be split into chunks of frames for these (validated) parameters.

        Empty when a frame's result depends on other frames; override when that depends on a
        parameter (e.g. continuity from the previous frame).
        """
        return cls.frame_inputs

    @classmethod
    def describe(cls) -> dict[str, Any]:
        return {
            "name": cls.name,
            "version": cls.version,
            "description": cls.description,
            "parameters": cls.parameters.describe(),
            "inputs": [p.describe() for p in cls.inputs],
            "outputs": [p.describe() for p in cls.outputs],
        }


def role_problem(cls: type[Algorithm]) -> str:
    """Why ``cls`` does not fill the roles it declares (an unknown role, a missing port), or ``""``."""
    for role in cls.roles:
        if role not in ROLES:
            return f"algorithm {cls.name!r} declares the unknown role {role!r}; roles: {', '.join(sorted(ROLES))}"
        inputs, outputs = ROLES[role]
        missing = [f"input {n!r}" for n in inputs if n not in {p.name for p in cls.inputs}]
        missing += [f"output {n!r}" for n in outputs if n not in {p.name for p in cls.outputs}]
        if missing:
            return f"algorithm {cls.name!r} declares the role {role!r} but has no {' and no '.join(missing)}"
    return ""


@dataclass
class RunOutcome:
    """What :func:`execute` returns: outputs or the error, and the parameters as validated."""

    outputs: dict[str, Any]
    params: dict[str, Any]
    status: str
    error: str = ""
    traceback: str = ""
    extra: dict[str, Any] = field(default_factory=dict)


def execute(algorithm: type[Algorithm], inputs: Mapping[str, np.ndarray], params: Mapping[str, Any],
            context: RunContext | None = None) -> RunOutcome:
    """Validate ``params`` and ``inputs``, run ``algorithm``, check its outputs.

    Free of global state: safe to call in another process on copies of the inputs.
    Validation errors raise; failures inside ``run`` are returned as ``status="failed"``, a run
    stopped through ``context.cancel`` as ``status="cancelled"`` (no outputs either way).
    """
    values = algorithm.parameters.validate(dict(params), where=f"{algorithm.name}.parameters")
    takes = ", ".join(p.name for p in algorithm.inputs) or "none"
    unknown = sorted(set(inputs) - {p.name for p in algorithm.inputs})  # a misspelt name first: it explains a missing one
    missing = [p.name for p in algorithm.inputs if not p.optional and p.name not in inputs]
    problems = [Problem(f"{algorithm.name}.inputs.{name}", f"{algorithm.name} does not take the input {name!r}; "
                        f"it takes: {takes}") for name in unknown]
    problems += [Problem(f"{algorithm.name}.inputs.{name}", f"{algorithm.name} needs the input(s) {name}; "
                         f"it takes: {takes}") for name in missing]
    if problems:
        raise AlgorithmInputError(problems)
    context = context or RunContext()
    try:
        context.check()  # a stop requested before the run starts: do not start it
        outputs = algorithm().run(inputs, values, context)
    except Cancelled as exc:
        return RunOutcome({}, values, "cancelled", str(exc))
    except Exception as exc:  # recorded in the result group, never lost
        return RunOutcome({}, values, "failed", f"{type(exc).__name__}: {exc}", traceback.format_exc())
    declared = [p.name for p in algorithm.outputs]
    absent = [name for name in declared if name not in outputs]
    if absent:
        return RunOutcome({}, values, "failed",
                          f"{algorithm.name} did not return the declared output(s) {', '.join(absent)}")
    undeclared = sorted(set(outputs) - set(declared))
    if undeclared:  # every stored dataset carries its declared unit and description
        return RunOutcome({}, values, "failed", f"{algorithm.name} returned undeclared output(s) "
                          f"{', '.join(undeclared)}; declare each as a Port in {algorithm.name}.outputs")
    arrays = {name: np.asarray(outputs[name]) for name in declared}
    unstorable = [f"{name} ({a.dtype})" for name, a in arrays.items() if a.dtype.kind in "OUMm"]
    if unstorable:
        return RunOutcome({}, values, "failed", f"{algorithm.name} returned output(s) HDF5 cannot store: "
                          f"{', '.join(unstorable)}; return numbers, booleans or bytes (dtype 'S')")
    return RunOutcome(arrays, values, "ok")


#: A run label: a letter, then letters, digits, ``_``, ``-`` or ``.`` (it appears in ``@label/output``).
LABEL_PATTERN = re.compile(r"[A-Za-z][A-Za-z0-9_.-]{0,63}")


def label_problem(label: str, algorithms: Collection[str]) -> str | None:
    """Why ``label`` cannot name a run (``None`` if it can).

    A label must match :data:`LABEL_PATTERN` and must not be the name of an algorithm in
    ``algorithms``: ``@name/output`` would then be ambiguous.

    >>> label_problem("first", ["derivatives"]) is None
    True
    >>> label_problem("derivatives", ["derivatives"])
    "'derivatives' is the name of an algorithm; @derivatives/... would be ambiguous: choose another label"
    """
    if not LABEL_PATTERN.fullmatch(label):
        return (f"{label!r} is not a run label: use a letter, then letters, digits, '_', '-' or '.' "
                "(at most 64 characters), e.g. 'first_pass'")
    if label in algorithms:
        return f"{label!r} is the name of an algorithm; @{label}/... would be ambiguous: choose another label"
    return None


@dataclass(frozen=True)
class ResultRef:
    """Where one algorithm run is stored: ``/results/<algorithm>/<run_id>``.

    ``status`` is ``ok``, ``failed``, ``cancelled`` or ``incomplete`` (no status stored: the
    writing of the run was interrupted); ``label`` is the run label given to :meth:`Session.run`
    (``""`` if none).
    """

    algorithm: str
    run_id: str
    status: str
    error: str = ""
    label: str = ""

    @property
    def path(self) -> str:
        return f"/results/{self.algorithm}/{self.run_id}"

    def require_ok(self, error: type[Exception] = AlgorithmError) -> ResultRef:
        """This reference if the run succeeded, else raise ``error`` naming the run and repeating its error.

        Examples
        --------
        >>> ResultRef("derivatives", "run-0002", "failed", "time is not increasing").require_ok()
        Traceback (most recent call last):
        ...
        mirrorlab.core.errors.AlgorithmError: /results/derivatives/run-0002 failed: time is not increasing
        """
        if self.status != "ok":
            raise error(f"{self.path} failed: {self.error}")
        return self


#: Each input's digest entry for a run's provenance (:func:`~mirrorlab.core.digests.input_entry`), by input name.
InputDigests = dict[str, dict[str, Any]]


class AlgorithmExecutor(Protocol):
    """What :attr:`Session.executor <mirrorlab.core.session.Session.executor>` may be: runs the session's
    algorithms instead of this process (:mod:`mirrorlab.core.batch.executors`: in place with a note of
    where, or in chunks of frames on Dask workers)."""

    @property
    def provenance(self) -> Mapping[str, Any]:
        """Where and how it runs (JSON-able), stored with every result as ``@executor``."""
        ...

    def __call__(self, session: Session, cls: type[Algorithm], inputs: Mapping[str, Any], params: Mapping[str, Any],
                 context: RunContext) -> tuple[RunOutcome, InputDigests]:
        """Run ``cls`` on ``inputs`` (h5py datasets of the session file, or arrays) with ``params``, reporting to
        ``context``; return the outcome and the digest entry of each input, hashed as it was read."""
        ...
