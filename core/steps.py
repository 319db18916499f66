"""Recipe steps: what ``[[steps]]`` tables in a recipe do, in order.

A step kind subclasses :class:`Step` and is registered through the
``mirrorlab_register_steps`` hook (this module registers the built-ins ``acquire``, ``wait`` and
``run``), so plugins add kinds such as ``calibrate`` or ``track`` without touching the core.
Validation happens for every step before the session starts; :meth:`Step.execute` then runs it
on the open session.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, ClassVar

from .errors import PluginError, Problem
from .hookspecs import hookimpl
from .params import Parameter, ParameterSet

if TYPE_CHECKING:
    from .registry import Registry
    from .session import Session


class Step(ABC):
    """Base class of recipe step kinds.

    ``parameters`` declares the keys of the step's table (besides ``action``). Override
    :meth:`validate` for keys that need more than typed scalars (nested tables).
    """

    name: ClassVar[str]
    version: ClassVar[str] = "1.0.0"
    description: ClassVar[str]
    parameters: ClassVar[ParameterSet] = ParameterSet()

    @classmethod
    def validate(cls, table: Mapping[str, Any], where: str, file: str | None,
                 registry: Registry, instruments: Mapping[str, Any]) -> tuple[dict[str, Any], list[Problem]]:
        """Typed values of the step's table and every problem found (file, key path, reason)."""
        return cls.parameters.problems(table, where, file)

    @abstractmethod
    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        """Run the step on an open, writable session."""


class Acquire(Step):
    name = "acquire"
    description = "record every instrument of the session for a duration"
    parameters = ParameterSet(
        Parameter("seconds", float, unit="s", bounds=(0.0, 7 * 24 * 3600.0), help="how long to record"),
    )

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        session.record(values["seconds"])


class Wait(Step):
    name = "wait"
    description = "pause between steps (e.g. to let a mechanism settle)"
    parameters = ParameterSet(Parameter("seconds", float, unit="s", bounds=(0.0, 3600.0), help="pause"))

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        end = time.monotonic() + values["seconds"]
        while (left := end - time.monotonic()) > 0:
            session.events.progress("wait", values["seconds"] - left, values["seconds"], "waiting")
            time.sleep(min(0.1, left))


class Run(Step):
    name = "run"
    description = "run an algorithm on datasets of the session and store its result"
    parameters = ParameterSet(Parameter("algorithm", str, help="registered algorithm name"))

    @classmethod
    def validate(cls, table: Mapping[str, Any], where: str, file: str | None,
                 registry: Registry, instruments: Mapping[str, Any]) -> tuple[dict[str, Any], list[Problem]]:
        scalar = {k: v for k, v in table.items() if k not in ("inputs", "parameters")}
        values, problems = cls.parameters.problems(scalar, where, file)
        if problems:
            return values, problems
        try:
            algorithm = registry.algorithm(values["algorithm"])
        except PluginError as exc:
            return values, [Problem(f"{where}.algorithm", str(exc), file)]
        inputs = table.get("inputs", {})
        if not isinstance(inputs, Mapping):
            problems.append(Problem(f"{where}.inputs", "must be a table of input name = dataset path", file))
            inputs = {}
        declared = {p.name for p in algorithm.inputs}
        for name, path in inputs.items():
            if name not in declared:
                problems.append(Problem(f"{where}.inputs.{name}", f"{algorithm.name} takes no input {name!r}; "
                                        f"it takes: {', '.join(sorted(declared)) or 'none'}", file))
            elif not isinstance(path, str) or not path.startswith(("/", "@")):
                problems.append(Problem(f"{where}.inputs.{name}", "must be an absolute dataset path such as "
                                        "'/instruments/cam/frames/data' or a result '@algorithm/output'", file))
        for p in algorithm.inputs:
            if not p.optional and p.name not in inputs:
                problems.append(Problem(f"{where}.inputs.{p.name}", f"required input of {algorithm.name} "
                                        f"({p.description})", file))
        params = table.get("parameters", {})
        if not isinstance(params, Mapping):
            problems.append(Problem(f"{where}.parameters", "must be a table", file))
            params = {}
        typed, more = algorithm.parameters.problems(params, f"{where}.parameters", file)
        problems += more
        values.update(inputs=dict(inputs), parameters=typed)
        return values, problems

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        session.run(values["algorithm"], values["inputs"], values["parameters"])


@hookimpl
def mirrorlab_register_steps() -> list[type[Step]]:
    return [Acquire, Wait, Run]
