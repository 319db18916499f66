"""Recipe steps: what ``[[steps]]`` tables in a recipe do, in order.

A step kind subclasses :class:`Step` and is registered through the
``mirrorlab_register_steps`` hook (this module registers the built-ins ``acquire``, ``preview``,
``wait`` and ``run``), so plugins add kinds such as ``calibrate`` or ``track`` without touching the core.
Validation happens for every step before the session starts; :meth:`Step.execute` then runs it
on the open session.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Collection, Mapping
from typing import TYPE_CHECKING, Any, ClassVar

from .algorithms import label_problem
from .errors import AlgorithmError, PluginError, Problem
from .hookspecs import hookimpl
from .params import Parameter, ParameterSet

if TYPE_CHECKING:
    from .algorithms import Algorithm, ResultRef
    from .registry import Registry
    from .session import Session


#: The nested tables of a step that runs an algorithm (see :func:`algorithm_tables`).
ALGORITHM_TABLES = {
    "inputs": "input name = dataset path ('/instruments/cam/frames/data') or earlier result ('@algorithm/output', "
              "'@label/output')",
    "parameters": "the algorithm's parameters (`mirrorlab plugins show ALGORITHM` lists them)",
}


class Step(ABC):
    """Base class of recipe step kinds.

    ``parameters`` declares the keys of the step's table (besides ``action``). Override :meth:`check`
    for what the typed values must satisfy together (a file that must exist, keys that go together),
    and :meth:`validate` for keys that need more than typed scalars (nested tables).
    """

    name: ClassVar[str]
    version: ClassVar[str] = "1.0.0"
    description: ClassVar[str]
    parameters: ClassVar[ParameterSet] = ParameterSet()
    #: Nested tables the step's table may hold (validated by :meth:`validate`): name -> what goes in it.
    tables: ClassVar[Mapping[str, str]] = {}
    #: The step records from instruments: not allowed in an analysis recipe on an existing session.
    records: ClassVar[bool] = False
    #: Parameters whose value names instruments of the recipe (comma-separated labels; empty names
    #: none), checked by :meth:`validate`.
    instrument_keys: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def validate(cls, table: Mapping[str, Any], where: str, file: str | None,
                 registry: Registry, instruments: Mapping[str, Any]) -> tuple[dict[str, Any], list[Problem]]:
        """Typed values of the step's table and every problem found (file, key path, reason): those of
        :meth:`scalars`, else those of :meth:`check`; and the labels that name no instrument of the recipe."""
        values, problems = cls.scalars(table, where, file)
        if not problems:
            problems = cls.check(values, where, file, registry)
        return values, problems + instrument_problems(values, cls.instrument_keys, where, file, instruments)

    @classmethod
    def check(cls, values: Mapping[str, Any], where: str, file: str | None, registry: Registry) -> list[Problem]:
        """Problems of the step's typed ``values`` taken together, once each is valid (default: none)."""
        return []

    @classmethod
    def scalars(cls, table: Mapping[str, Any], where: str, file: str | None) -> tuple[dict[str, Any], list[Problem]]:
        """Typed values of the step's :attr:`parameters` in ``table`` (its nested :attr:`tables` are left
        to :meth:`validate`), and every problem; an unknown key is reported with every key the step
        takes: ``action``, the parameters and the tables."""
        return cls.parameters.problems(table, where, file, others=("action", *cls.tables))

    @classmethod
    def session_problems(cls, session: Session, values: Mapping[str, Any], where: str) -> list[Problem]:
        """What in an existing ``session`` would make this step fail before it stores anything
        (a group or run label it would create is there already).

        An analysis recipe run on an existing session checks every step with this before the first
        one runs, so that a second run of the recipe stops at once, naming the key, instead of
        after some of its results were appended. The default finds nothing.
        """
        return []

    @abstractmethod
    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        """Run the step on an open, writable session."""


class Acquire(Step):
    name = "acquire"
    description = "record the instruments of the session for a duration, or until their sources end"
    records = True
    parameters = ParameterSet(
        Parameter("seconds", float, 0.0, unit="s", bounds=(0.0, 7 * 24 * 3600.0),
                  help="how long to record; 0 = until every recorded source has ended"),
        Parameter("instruments", str, "", help="comma-separated labels to record (default: all)"),
    )
    instrument_keys = ("instruments",)

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        session.record(values["seconds"], _labels(values["instruments"]) or None)


class Preview(Acquire):  # validated like acquire (seconds, instruments)
    name = "preview"
    description = "acquire without recording (align, focus, let a control loop settle)"
    parameters = ParameterSet(
        Parameter("seconds", float, unit="s", bounds=(0.0, 7 * 24 * 3600.0),
                  help="how long to acquire; 0 = until every source has ended"),
        Parameter("instruments", str, "", help="comma-separated labels to acquire (default: all)"),
    )

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        session.preview(values["seconds"], _labels(values["instruments"]) or None)


class Wait(Step):
    name = "wait"
    description = "pause between steps (e.g. to let a mechanism settle)"
    parameters = ParameterSet(Parameter("seconds", float, unit="s", bounds=(0.0, 3600.0), help="pause"))

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        end = time.monotonic() + values["seconds"]
        while (left := end - time.monotonic()) > 0 and not session.stop_requested:
            session.events.progress("wait", values["seconds"] - left, values["seconds"], "waiting")
            time.sleep(min(0.1, left))


class AlgorithmStep(Step):
    """Base of step kinds that run a registered algorithm, with its ``inputs`` and ``parameters`` tables.

    :meth:`validate` checks the step's own keys (:attr:`parameters`), finds the algorithm that
    :meth:`algorithm_name` names (an unknown one is reported at :attr:`algorithm_key`), adds the
    problems of :meth:`check` (called once the algorithm is known) and then those of the two tables
    (:func:`algorithm_tables`; the inputs of :meth:`provided` may be left out). The typed values hold
    the tables as ``inputs`` and ``parameters``. :meth:`run_algorithm` runs it in :meth:`execute`.
    """

    tables = ALGORITHM_TABLES
    #: The key of the step's table that names the algorithm (blamed when no such algorithm is registered).
    algorithm_key: ClassVar[str] = "algorithm"
    #: What :meth:`run_algorithm` raises when the run fails.
    failure: ClassVar[type[AlgorithmError]] = AlgorithmError

    @classmethod
    def algorithm_name(cls, values: Mapping[str, Any]) -> str:
        """The registered algorithm the step runs, from its typed ``values`` (default: ``values[algorithm_key]``)."""
        return str(values[cls.algorithm_key])

    @classmethod
    def provided(cls, values: Mapping[str, Any]) -> Collection[str]:
        """Inputs of the algorithm that the step supplies itself, so the recipe need not name them."""
        return ()

    @classmethod
    def validate(cls, table: Mapping[str, Any], where: str, file: str | None,
                 registry: Registry, instruments: Mapping[str, Any]) -> tuple[dict[str, Any], list[Problem]]:
        values, problems = cls.scalars(table, where, file)
        if problems:
            return values, problems
        try:
            algorithm = registry.algorithm(cls.algorithm_name(values))
        except PluginError as exc:
            return values, [Problem(f"{where}.{cls.algorithm_key}", str(exc), file)]
        problems = cls.check(values, where, file, registry)
        inputs, params, more = algorithm_tables(algorithm, table, where, file, cls.provided(values))
        values.update(inputs=inputs, parameters=params)
        return values, problems + more + instrument_problems(values, cls.instrument_keys, where, file, instruments)

    def run_algorithm(self, session: Session, name: str, inputs: Mapping[str, Any], parameters: Mapping[str, Any],
                      label: str | None = None) -> ResultRef:
        """Run ``name`` on the session; a failed run (stored with its error) raises :attr:`failure`,
        since later steps would only fail on its absence."""
        return session.run(name, inputs, parameters, label=label).require_ok(self.failure)


class Run(AlgorithmStep):
    name = "run"
    description = "run an algorithm on datasets of the session and store its result"
    parameters = ParameterSet(
        Parameter("algorithm", str, help="registered algorithm name"),
        Parameter("as", str, "", help="run label, unique in the session: later steps name this run's "
                                      "outputs '@label/output' (default: none)"),
    )

    @classmethod
    def check(cls, values: Mapping[str, Any], where: str, file: str | None, registry: Registry) -> list[Problem]:
        reason = label_problem(values["as"], registry.names("algorithm")) if values["as"] else None
        return [Problem(f"{where}.as", reason, file)] if reason else []

    @classmethod
    def session_problems(cls, session: Session, values: Mapping[str, Any], where: str) -> list[Problem]:
        taken = [r for r in session.results() if values["as"] and r.label == values["as"] and r.status == "ok"]
        return [Problem(f"{where}.as", f"run label {values['as']!r} already names {taken[0].path} in "
                                       f"{session.path.name}; labels are unique in a session")] if taken else []

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        self.run_algorithm(session, values["algorithm"], values["inputs"], values["parameters"],
                           label=values["as"] or None)


def algorithm_tables(algorithm: type[Algorithm], table: Mapping[str, Any], where: str, file: str | None,
                     provided: Collection[str] = ()) -> tuple[dict[str, str], dict[str, Any], list[Problem]]:
    """Validate a step's ``inputs`` and ``parameters`` tables against ``algorithm``.

    Inputs are dataset paths (``"/instruments/cam/frames/data"``) or result references
    (``"@algorithm/output"``, see :meth:`Session.resolve`); ``provided`` names inputs the step
    supplies itself. Returns the inputs, the typed parameters and every problem found.
    """
    problems: list[Problem] = []
    inputs = _table(table, "inputs", where, file, problems)
    declared = {p.name for p in algorithm.inputs}
    for name, path in inputs.items():
        if name not in declared:
            problems.append(Problem(f"{where}.inputs.{name}", f"{algorithm.name} takes no input {name!r}; "
                                    f"it takes: {', '.join(sorted(declared)) or 'none'}", file))
        elif not isinstance(path, str) or not path.startswith(("/", "@")):
            problems.append(Problem(f"{where}.inputs.{name}", "must be an absolute dataset path such as "
                                    "'/instruments/cam/frames/data' or a result '@algorithm/output' "
                                    "or '@label/output'", file))
    for p in algorithm.inputs:
        if not p.optional and p.name not in inputs and p.name not in provided:
            problems.append(Problem(f"{where}.inputs.{p.name}", f"required input of {algorithm.name} "
                                    f"({p.description})", file))
    params = _table(table, "parameters", where, file, problems)
    typed, more = algorithm.parameters.problems(params, f"{where}.parameters", file)
    return inputs, typed, problems + more


def _table(table: Mapping[str, Any], key: str, where: str, file: str | None, problems: list[Problem]) -> dict:
    value = table.get(key, {})
    if not isinstance(value, Mapping):
        problems.append(Problem(f"{where}.{key}", "must be a table", file))
        return {}
    return dict(value)


def _labels(text: str) -> list[str]:
    return [label.strip() for label in text.split(",") if label.strip()]


def instrument_problems(values: Mapping[str, Any], keys: Collection[str], where: str, file: str | None,
                        instruments: Mapping[str, Any]) -> list[Problem]:
    """A problem for each label in ``values[key]`` (``key`` in ``keys``) that names no instrument of the recipe.

    An analysis recipe declares no instruments (they are in the session file it runs on): nothing
    is checked then; the step finds out when it runs.
    """
    if not instruments:
        return []
    return [Problem(f"{where}.{key}", f"no instrument {label!r} in the recipe; it has: {', '.join(instruments)}", file)
            for key in keys for label in _labels(str(values.get(key) or "")) if label not in instruments]


@hookimpl
def mirrorlab_register_steps() -> list[type[Step]]:
    return [Acquire, Preview, Wait, Run]
