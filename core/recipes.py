"""Recipes: TOML files that script a session.

::

    [session]
    description = "scan three frames of film"
    operator = "ana"

    [instruments.cam]              # one table per instrument, named by the recipe
    plugin = "film_scanner"        # a registered instrument plugin
    simulate = true                # start its simulator, drive it through the real driver
    [instruments.cam.settings]     # typed, validated against the plugin's parameters
    lines = 344
    [instruments.cam.simulator]    # only with simulate = true
    clock = "FAST"

    [controllers.loop]             # optional: live logic between streams and instruments
    plugin = "follow"              # a registered controller plugin
    inputs = { input = "tracker/angle" }        # role = "<instrument>/<stream>"
    instruments = { output = "mirror" }          # role = instrument label
    [controllers.loop.settings]
    gain = 0.5

    [world]                        # optional: one simulated scene for every simulated instrument
    scene = "walk"                 # keys: the world_parameters of the recipe's simulated plugins

    [[steps]]                      # executed in order
    action = "acquire"             # a registered step kind: preview | acquire | wait | run | ...
    seconds = 10

:func:`load_recipe` validates *everything* before anything starts and reports every problem with
file, key path and reason. ``--set KEY=VALUE`` overrides (``instruments.cam.settings.lines=64``,
``steps.0.seconds=2``) are applied first and stored with the recipe text in the session file.

A relative path in a setting that names a file or folder (a :class:`Parameter` with ``path``:
a motion file, a frame folder, a figures folder) is relative to the recipe's own folder, whatever
the working folder, in every table: instrument settings, controller settings, ``[world]`` and steps
(also when given with ``--set``).

A recipe stays inside: what it writes (a :class:`Parameter` with ``output``: a figures folder, a
CSV file) is inside its own folder or the session file's and replaces nothing without
``--overwrite`` (:func:`output_problems`); an instrument's ``port`` is a device path, ``socket://``,
``loop://`` or ``rfc2217://`` unless ``--allow-port-url``; instrument and controller labels, which
name HDF5 groups, are identifiers (:data:`~mirrorlab.core.params.IDENTIFIER`); the session's
description and operator hold no control characters.
"""

from __future__ import annotations

import hashlib
import json
import os
import tomllib
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .algorithms import AlgorithmExecutor
from .devices.transport import port_problem
from .errors import MirrorlabError, PluginError, Problem, StoppedOnRequest, ValidationError
from .params import Parameter, ParameterSet, control_problem, identifier_problem
from .registry import Registry, get_registry
from .session import SIMULATOR_OPTIONS, Session

if TYPE_CHECKING:
    from .steps import Step

SESSION_KEYS = ParameterSet(
    Parameter("description", str, "", help="what the session is"),
    Parameter("operator", str, "", help="who runs it"),
)
INSTRUMENT_KEYS = ParameterSet(
    Parameter("plugin", str, help="registered instrument plugin"),
    Parameter("simulate", bool, False, help="drive the plugin's simulator instead of a device"),
    Parameter("port", str, "", help="device path or pyserial URL of the real device"),
    Parameter("timeout", float, 2.0, unit="s", bounds=(0.01, 600.0), help="seconds per device call"),
    Parameter("reconnect", float, 60.0, unit="s", bounds=(0.0, 7 * 24 * 3600.0),
              help="seconds of reconnect attempts after a lost connection before the instrument fails (0: never)"),
)
CONTROLLER_TABLES = ("settings", "inputs", "instruments")
#: How deep tables and arrays of a recipe may nest: a real recipe needs 4 (a list of points in a
#: step); far deeper ones only exhaust Python's recursion in the TOML parser or the JSON copy.
MAX_DEPTH = 32


@dataclass
class InstrumentPlan:
    label: str
    plugin: str
    simulate: bool
    port: str
    timeout: float
    reconnect: float
    settings: dict[str, Any]
    simulator: dict[str, Any]


@dataclass
class ControllerPlan:
    label: str
    plugin: str
    settings: dict[str, Any]
    inputs: dict[str, str]
    instruments: dict[str, str]


@dataclass
class StepPlan:
    index: int
    action: str
    cls: type[Step]
    values: dict[str, Any]


@dataclass
class Recipe:
    """A validated recipe, ready to run."""

    path: Path
    text: str
    overrides: list[str]
    data: dict[str, Any]
    description: str
    operator: str
    instruments: list[InstrumentPlan] = field(default_factory=list)
    steps: list[StepPlan] = field(default_factory=list)
    controllers: list[ControllerPlan] = field(default_factory=list)
    world: dict[str, Any] | None = None
    #: What the recipe writes: (key, path, "file" or "folder") of every :attr:`Parameter.output` it sets.
    outputs: list[tuple[str, str, str]] = field(default_factory=list)

    def default_output(self, root: Path | None = None) -> Path:
        """``sessions/out/<recipe>-<UTC timestamp>.h5`` next to the recipe's folder."""
        stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
        base = root if root is not None else self.path.resolve().parent / "out"
        return base / f"{self.path.stem}-{stamp}.h5"


def parse_override(text: str) -> tuple[list[str], Any]:
    """``"a.b.c=VALUE"`` → (``["a", "b", "c"]``, value parsed as TOML, else the raw string)."""
    key, sep, raw = text.partition("=")
    if not sep or not key.strip():
        raise ValidationError([Problem("--set", f"{text!r} is not KEY=VALUE (e.g. steps.0.seconds=2)")])
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    except RecursionError:  # deeper than the parser goes
        value = None
    if value is None or _too_deep(value, key.count(".") + 1):
        raise ValidationError([Problem("--set " + key.strip(), f"the value nests deeper than {MAX_DEPTH} levels of "
                                       "tables and arrays; give a plain value")])
    return key.strip().split("."), value


def _apply_override(data: dict[str, Any], keys: list[str], value: Any) -> None:
    instruments = data.get("instruments")
    if keys[0] == "instruments" and len(keys) > 1 and isinstance(instruments, Mapping) and keys[1] not in instruments:
        # a new table would only be blamed on the recipe ("plugin: required"): name the option's mistake
        raise ValidationError([Problem("--set " + ".".join(keys), f"no instrument {keys[1]!r} in the recipe; "
                                       f"it has: {', '.join(instruments) or 'none'}")])
    node: Any = data
    for i, key in enumerate(keys[:-1]):
        if isinstance(node, list):
            if not key.isdigit() or int(key) >= len(node):
                raise ValidationError([Problem("--set " + ".".join(keys),
                                               f"{'.'.join(keys[:i])} has no item {key}")])
            node = node[int(key)]
        elif isinstance(node, dict):
            node = node.setdefault(key, {})
        else:
            raise ValidationError([Problem("--set " + ".".join(keys), f"{'.'.join(keys[:i])} is a value, not a table")])
    last = keys[-1]
    if isinstance(node, list):
        if not last.isdigit() or int(last) >= len(node):
            raise ValidationError([Problem("--set " + ".".join(keys), f"no item {last}")])
        node[int(last)] = value
    elif isinstance(node, dict):
        node[last] = value
    else:
        raise ValidationError([Problem("--set " + ".".join(keys), "does not name a table key")])


def load_recipe(path: str | Path, overrides: Sequence[str] = (), registry: Registry | None = None,
                analysis: bool = False, allow_port_url: bool = False) -> Recipe:
    """Read, override and validate a recipe; raise :class:`ValidationError` listing every problem.

    ``analysis``: the recipe is to run on an existing session (:func:`run_analysis`), so it may
    declare no instruments and no step that records. ``allow_port_url``: a port may be any pyserial
    URL (``--allow-port-url``), not only a device path, ``socket://``, ``loop://`` or ``rfc2217://``.
    What the recipe writes is checked against the session's folder by :func:`output_problems`.
    """
    path = Path(path)
    file = str(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except OSError as exc:
        raise ValidationError([Problem("", f"cannot read the recipe: {exc.strerror}; check the path", file)]) from None
    except UnicodeDecodeError as exc:
        raise ValidationError([Problem("", f"not a TOML recipe: byte {exc.start} is not UTF-8 text "
                                       "(a session file or other binary?); give a .toml recipe", file)]) from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ValidationError([Problem("", f"not a TOML recipe: {exc}; fix the TOML syntax there", file)]) from None
    except RecursionError:  # deeper than the parser goes
        data = None
    if data is None or _too_deep(data, 0):
        raise ValidationError([Problem("", f"tables or arrays nest deeper than {MAX_DEPTH} levels; a recipe needs "
                                       "a few (see docs/ARCHITECTURE.md, Recipes)", file)])
    for item in overrides:
        keys, value = parse_override(item)
        _apply_override(data, keys, value)
    registry = registry or get_registry()
    problems: list[Problem] = []
    folder = path.resolve().parent

    for key in data:
        if key not in ("session", "instruments", "controllers", "steps", "world"):
            problems.append(Problem(key, "unknown top-level table; expected session, instruments, controllers, "
                                    "world, steps", file))
    session, more = SESSION_KEYS.problems(_table(data, "session", problems, file), "session", file)
    problems += more
    problems += [Problem(f"session.{key}", reason, file) for key in ("description", "operator")
                 if (reason := control_problem(session.get(key, "")))]
    outputs: list[tuple[str, str, str]] = []

    instruments: list[InstrumentPlan] = []
    for label, table in _table(data, "instruments", problems, file).items():
        where = f"instruments.{label}"
        if reason := identifier_problem(label):  # it names the group /instruments/<label>
            problems.append(Problem(where, f"{reason}; it names the instrument's group in the session file", file))
        if not isinstance(table, Mapping):
            problems.append(Problem(where, "must be a table", file))
            continue
        top = {k: v for k, v in table.items() if k not in ("settings", "simulator")}
        values, more = INSTRUMENT_KEYS.problems(top, where, file)
        problems += more
        if "plugin" not in values:
            continue
        invalid = set(top) - set(values)
        values = {**INSTRUMENT_KEYS.defaults(), **values}  # invalid keys are reported; check the rest on defaults
        try:
            cls = registry.instrument(values["plugin"])
        except PluginError as exc:
            problems.append(Problem(f"{where}.plugin", str(exc), file))
            continue
        settings, more = cls.parameters.problems(beside(folder, _table(table, "settings", problems, file, where),
                                                        cls.parameters), f"{where}.settings", file)
        problems += more
        outputs += _outputs(f"{where}.settings", settings, cls.parameters)
        if values["port"] and not allow_port_url and (reason := port_problem(values["port"])):
            problems.append(Problem(f"{where}.port", reason, file))
        sim_table = _table(table, "simulator", problems, file, where)
        simulator, more = SIMULATOR_OPTIONS.problems(sim_table, f"{where}.simulator", file)
        problems += more
        if values.get("simulate") and not cls.has_simulator():
            problems.append(Problem(f"{where}.simulate", f"{cls.name} has no simulator", file))
        # (a `simulate` of the wrong type is its own problem, not a missing port)
        if ("simulate" not in invalid and not values["simulate"] and not values.get("port")
                and cls.needs_port({**cls.parameters.defaults(), **settings})):
            problems.append(Problem(f"{where}.port", "required unless simulate = true "
                                    "(device path or pyserial URL)", file))
        instruments.append(InstrumentPlan(label, values["plugin"], values["simulate"], values["port"],
                                          values["timeout"], values["reconnect"], settings, simulator))

    world = _world(data, instruments, registry, problems, file, folder, outputs) if "world" in data else None
    controllers = [plan for label, table in _table(data, "controllers", problems, file).items()
                   if (plan := _controller_plan(label, table, instruments, registry, problems, file, folder, outputs))]

    steps: list[StepPlan] = []
    raw_steps = data.get("steps", [])
    if not isinstance(raw_steps, list):
        problems.append(Problem("steps", "must be an array of tables ([[steps]])", file))
        raw_steps = []
    labels = {p.label: p for p in instruments}
    for i, table in enumerate(raw_steps):
        where = f"steps.{i}"
        if not isinstance(table, Mapping) or "action" not in table:
            problems.append(Problem(where, "each step needs action = \"...\"", file))
            continue
        try:
            step_cls = registry.step(str(table["action"]))
        except PluginError as exc:
            problems.append(Problem(f"{where}.action", str(exc), file))
            continue
        rest = beside(folder, {k: v for k, v in table.items() if k != "action"}, step_cls.parameters)
        values, more = step_cls.validate(rest, where, file, registry, labels)
        problems += more
        outputs += _outputs(where, values, step_cls.parameters)
        if analysis and step_cls.records:
            problems.append(Problem(f"{where}.action", f"{step_cls.name!r} records from instruments; a recipe run on "
                                    "an existing session (--session) holds analysis steps only", file))
        steps.append(StepPlan(i, step_cls.name, step_cls, values))
    if analysis and instruments:
        problems.append(Problem("instruments", "a recipe run on an existing session (--session) declares no "
                                "instruments; the session's recordings are its inputs", file))
    if analysis and controllers:
        problems.append(Problem("controllers", "a recipe run on an existing session (--session) declares no "
                                "controllers: nothing acquires there", file))
    problems += _run_label_problems(steps, file)
    if not steps and not problems:
        problems.append(Problem("steps", "the recipe has no [[steps]]; nothing would happen", file))
    if problems:
        raise ValidationError(problems)
    return Recipe(path, text, list(overrides), data, session["description"], session["operator"],
                  instruments, steps, controllers, world, outputs)


def _outputs(where: str, values: Mapping[str, Any], params: ParameterSet) -> list[tuple[str, str, str]]:
    """(key, path, "file" or "folder") of each output parameter ``values`` sets (see :attr:`Recipe.outputs`)."""
    return [(f"{where}.{name}", str(value), params[name].output) for name, value in values.items()
            if name in params and params[name].output and value]


def output_problems(recipe: Recipe, session: Path, overwrite: bool = False) -> list[Problem]:
    """What is wrong with the files and folders ``recipe`` writes (:attr:`Recipe.outputs`) for the
    session file ``session``: each must be inside the recipe's folder or the session file's (after
    following symbolic links: a link out of them is outside), and an existing file, or a folder
    already holding files, is replaced only with ``overwrite``.

    A recipe from another lab can name any path; this keeps what it writes where the user looks.
    """
    folders = [recipe.path.resolve().parent, session.resolve().parent]
    problems = []
    for key, given, kind in recipe.outputs:
        target = Path(given).resolve()  # follows every link on the way, as writing would
        if not any(target.is_relative_to(folder) for folder in folders):
            leads = f" (through a link: {str(target)!r})" if str(target) != given else ""
            problems.append(Problem(key, f"{given!r}{leads} is outside the recipe's folder ({folders[0]}) and the session "
                                    f"file's ({folders[1]}); name a {kind} inside one of them", str(recipe.path)))
        elif target.exists() and target.is_dir() != (kind == "folder"):
            problems.append(Problem(key, f"{given!r} is a {'folder' if target.is_dir() else 'file'}; name a {kind}",
                                    str(recipe.path)))
        elif not overwrite and (target.exists() if kind == "file" else _holds_files(target)):
            problems.append(Problem(key, f"{given!r} already {'exists' if kind == 'file' else 'holds files'}; add "
                                    f"--overwrite to replace {'it' if kind == 'file' else 'them'}, or name another "
                                    f"{kind}", str(recipe.path)))
    return problems


def _holds_files(folder: Path) -> bool:
    return folder.is_dir() and any(folder.iterdir())


def check_outputs(recipe: Recipe, session: Path, overwrite: bool = False) -> None:
    """Raise :class:`ValidationError` with the :func:`output_problems` of ``recipe``, if any."""
    if problems := output_problems(recipe, session, overwrite):
        raise ValidationError(problems)


def _too_deep(value: Any, depth: int) -> bool:
    """Whether ``value`` (parsed TOML at nesting level ``depth``) nests deeper than :data:`MAX_DEPTH`.

    >>> _too_deep({"a": [[1]]}, 0), _too_deep([1], MAX_DEPTH)
    (False, True)
    """
    stack = [(value, depth)]
    while stack:  # a loop, not recursion: the point is to survive what Python's recursion would not
        node, level = stack.pop()
        if isinstance(node, Mapping | list):
            if level >= MAX_DEPTH:
                return True
            stack.extend((item, level + 1) for item in (node.values() if isinstance(node, Mapping) else node))
    return False


def beside(folder: Path, table: Mapping[str, Any], params: ParameterSet) -> dict[str, Any]:
    """``table`` with every relative path of a path-valued parameter (:attr:`Parameter.path`) made
    relative to ``folder`` (the recipe's): the one rule for the files and folders a recipe names.

    Examples
    --------
    >>> params = ParameterSet(Parameter("motion", str, "", path=True), Parameter("joints", str, ""))
    >>> beside(Path("/lab/recipes"), {"motion": "../data/walk.bvh", "joints": "a,b"}, params)
    {'motion': '/lab/data/walk.bvh', 'joints': 'a,b'}
    >>> beside(Path("/lab/recipes"), {"motion": "/data/walk.bvh"}, params)
    {'motion': '/data/walk.bvh'}
    """
    def resolved(value: str) -> str:
        given = Path(value).expanduser()
        return os.path.normpath(given if given.is_absolute() else folder / given)  # "a/../b" as "b" in messages

    return {k: resolved(v) if k in params and params[k].path and isinstance(v, str) and v else v
            for k, v in table.items()}


def _world(data: Mapping[str, Any], instruments: list[InstrumentPlan], registry: Registry,
           problems: list[Problem], file: str, folder: Path, outputs: list[tuple[str, str, str]]) -> dict[str, Any] | None:
    """Validate ``[world]`` against the world parameters of the recipe's simulated instruments."""
    table = _table(data, "world", problems, file)
    sets: dict[int, ParameterSet] = {}
    for plan in instruments:
        params = registry.instrument(plan.plugin).world_parameters
        if plan.simulate and params is not None:
            sets.setdefault(id(params), params)
    if not sets:
        problems.append(Problem("world", "no simulated instrument of the recipe shares a world (their plugins "
                                "declare no world_parameters); remove [world] or simulate a tracker", file))
        return None
    values: dict[str, Any] = {}
    for params in sets.values():
        typed, more = params.problems(beside(folder, table, params), "world", file)
        problems += more
        outputs += _outputs("world", typed, params)
        values.update(typed)
    return values


def _controller_plan(label: str, table: Any, instruments: list[InstrumentPlan], registry: Registry,
                     problems: list[Problem], file: str, folder: Path,
                     outputs: list[tuple[str, str, str]]) -> ControllerPlan | None:
    """Validate ``[controllers.<label>]``: plugin, settings, and bindings to the recipe's instruments."""
    where = f"controllers.{label}"
    if reason := identifier_problem(label):  # it names the group /controllers/<label>
        problems.append(Problem(where, f"{reason}; it names the controller's group in the session file", file))
    if not isinstance(table, Mapping):
        problems.append(Problem(where, "must be a table", file))
        return None
    for key in set(table) - {"plugin", *CONTROLLER_TABLES}:
        problems.append(Problem(f"{where}.{key}", f"unknown key; expected plugin, {', '.join(CONTROLLER_TABLES)}", file))
    try:
        cls = registry.controller(str(table.get("plugin", "")))
    except PluginError as exc:
        problems.append(Problem(f"{where}.plugin", str(exc) if "plugin" in table else
                                "required: a registered controller (`mirrorlab plugins` lists them)", file))
        return None
    settings, more = cls.parameters.problems(beside(folder, _table(table, "settings", problems, file, where),
                                                    cls.parameters), f"{where}.settings", file)
    problems += more
    if more:
        return None
    outputs += _outputs(f"{where}.settings", settings, cls.parameters)
    inputs = {k: str(v) for k, v in _table(table, "inputs", problems, file, where).items()}
    bound = {k: str(v) for k, v in _table(table, "instruments", problems, file, where).items()}
    plans = {p.label: p for p in instruments}
    for role in sorted(set(inputs) ^ set(cls.inputs)):
        problems.append(Problem(f"{where}.inputs.{role}", f"{cls.name} has no input {role!r}" if role in inputs else
                                f"required: '<instrument>/<stream>' ({cls.inputs[role]})", file))
    for role, ref in inputs.items():
        instrument, _, stream = ref.partition("/")
        if role in cls.inputs and (instrument not in plans or not stream):
            problems.append(Problem(f"{where}.inputs.{role}", f"{ref!r} is not '<instrument>/<stream>' of an "
                                    f"instrument of the recipe ({', '.join(plans) or 'none'})", file))
    commanded = cls(label, settings).commanded()
    for role in sorted(set(bound) ^ set(commanded)):
        problems.append(Problem(f"{where}.instruments.{role}", f"{cls.name} commands no {role!r}" if role in bound
                                else "required: the label of an instrument of the recipe", file))
    for role, instrument in bound.items():
        if role not in commanded:
            continue
        plan = plans.get(instrument)
        if plan is None:
            problems.append(Problem(f"{where}.instruments.{role}", f"no instrument {instrument!r} in the recipe; "
                                    f"it has: {', '.join(plans) or 'none'}", file))
            continue
        params = registry.instrument(plan.plugin).parameters
        not_live = [n for n in commanded[role] if n not in params.setpoints]
        if not_live:
            problems.append(Problem(f"{where}.instruments.{role}", f"{plan.plugin} {instrument!r} has no "
                                    f"live-settable {', '.join(not_live)}, which {cls.name} sets", file))
    return ControllerPlan(label, cls.name, settings, inputs, bound)


def _run_label_problems(steps: Sequence[StepPlan], file: str) -> list[Problem]:
    """Run labels (``as = "..."``) used twice, and ``@label/...`` inputs that name a later step's label."""
    problems: list[Problem] = []
    declared: dict[str, int] = {}
    for step in steps:
        if step.values.get("as"):
            declared.setdefault(step.values["as"], step.index)
    for step in steps:
        label = step.values.get("as")
        if label and declared[label] != step.index:
            problems.append(Problem(f"steps.{step.index}.as", f"run label {label!r} is already used by "
                                    f"steps.{declared[label]}; labels must be unique in a session", file))
        inputs = step.values.get("inputs")
        for name, ref in (inputs.items() if isinstance(inputs, Mapping) else ()):
            named = ref[1:].partition("/")[0] if isinstance(ref, str) and ref.startswith("@") else None
            if named in declared and declared[named] >= step.index:
                problems.append(Problem(f"steps.{step.index}.inputs.{name}", f"{ref!r} names the run labelled "
                                        f"{named!r} of steps.{declared[named]}, which has not run yet at this "
                                        "step; refer to a label of an earlier step", file))
    return problems


def _table(data: Mapping[str, Any], key: str, problems: list[Problem], file: str, where: str = "") -> dict:
    value = data.get(key, {})
    if not isinstance(value, Mapping):
        problems.append(Problem(f"{where}.{key}" if where else key, "must be a table", file))
        return {}
    return dict(value)


def add_devices(session: Session, recipe: Recipe) -> None:
    """Connect the recipe's instruments, then bind its controllers, in an open session (nothing
    acquires yet): what ``mirrorlab run`` does before the first step and ``mirrorlab tui`` on opening.
    A recipe with a ``[world]`` gives the session that world first, so every simulator shares it."""
    if recipe.world is not None:
        session.set_world(recipe.world)
    for plan in recipe.instruments:
        session.add_instrument(plan.label, plan.plugin, port=plan.port or None, settings=plan.settings,
                               simulate=plan.simulate, simulator=plan.simulator, timeout=plan.timeout,
                               reconnect=plan.reconnect)
    for c in recipe.controllers:
        session.add_controller(c.label, c.plugin, settings=c.settings, inputs=c.inputs, instruments=c.instruments)


def run_steps(session: Session, steps: Sequence[StepPlan], on_step: Callable[[StepPlan], None] | None = None) -> None:
    """Execute ``steps`` in order on an open session, until one fails or a stop is requested.

    ``on_step(step)`` is called as each step starts (a ``step`` event is logged too). A step that
    raises because :meth:`Session.request_stop` interrupted it ends quietly; any other error propagates.
    """
    for step in steps:
        if session.stop_requested:
            return
        if on_step is not None:
            on_step(step)
        session.events.emit("info", "recipe", "step", f"step {step.index}: {step.action}", index=step.index)
        try:
            step.cls().execute(session, step.values)
        except MirrorlabError:
            if not session.stop_requested:
                raise


def recipe_record(recipe: Recipe) -> dict[str, Any]:
    """What :meth:`Session.create` stores under ``/config`` for this recipe (text, overrides, path, effective)."""
    return {"text": recipe.text, "overrides": recipe.overrides, "path": str(recipe.path),
            "effective": json.loads(json.dumps(recipe.data, default=str))}


def run_recipe(recipe: Recipe, out: Path, registry: Registry | None = None,
               on_session: Callable[[Session], None] | None = None, overwrite: bool = False) -> Path:
    """Run a validated recipe into a new session file; return its path.

    On failure the session is closed with status ``aborted`` (everything recorded is kept) and
    the error propagates; a failure before anything was recorded or stored (an instrument that
    would not connect) leaves no file (see :meth:`Session.create`). ``overwrite`` replaces an
    existing ``out``.

    :meth:`Session.request_stop` (the operator, or the first Ctrl-C of ``mirrorlab run``) ends
    the running step and runs no further one: the session is closed cleanly, the reason logged,
    and :class:`~mirrorlab.core.errors.StoppedOnRequest` raised after the file is closed. A
    :class:`KeyboardInterrupt` that gets through closes it ``aborted``, with the reason logged.
    """
    stopped = ""
    with Session.create(out, operator=recipe.operator, description=recipe.description, recipe=recipe_record(recipe),
                        registry=registry, overwrite=overwrite) as session:
        if on_session is not None:
            on_session(session)
        started: list[StepPlan] = []
        try:
            with session.operation():
                add_devices(session, recipe)
                run_steps(session, recipe.steps, started.append)
                if session.stop_requested:
                    where = (f"during step {started[-1].index} ({started[-1].action})" if started
                             else "before the first step")
                    stopped = f"stopped on request {where}; later steps were not run"
                    session.close(reason=stopped)
        except KeyboardInterrupt:
            where = f" during step {started[-1].index} ({started[-1].action})" if started else ""
            session.close("aborted", reason=f"interrupted (Ctrl-C){where}")
            raise
    if stopped:
        raise StoppedOnRequest(f"{stopped}; the session file keeps everything recorded: {out}")
    return out


def check_on_session(recipe: Recipe, session: Session) -> None:
    """Raise :class:`ValidationError` if a step of the analysis ``recipe`` would find what it
    creates (a calibration group, a run label) already in ``session``: checked before the first
    step runs, so that a second analysis of one file stops before appending anything."""
    problems = [problem for step in recipe.steps
                for problem in step.cls.session_problems(session, step.values, f"steps.{step.index}")]
    if problems:  # one line: what is taken, and the one remedy for all of it
        taken = "; ".join(str(problem) for problem in problems)
        raise ValidationError([Problem("", f"{session.path.name} holds the results of an earlier analysis ({taken}); "
                                           "run the recipe on a fresh copy of the recording (mirrorlab batch copies "
                                           "its inputs to --out), or give those keys new names with --set",
                                       str(recipe.path))])


def run_analysis(recipe: Recipe, path: Path, registry: Registry | None = None,
                 on_session: Callable[[Session], object] | None = None,
                 executor: AlgorithmExecutor | None = None) -> Path:
    """Run an analysis recipe's steps on an existing session file, appending their results; return its path.

    The recipe (loaded with ``analysis=True``) is logged with its path, hash and overrides; each
    result keeps its own provenance. ``executor`` (see :attr:`Session.executor`) runs the
    algorithms elsewhere, e.g. in chunks of frames on Dask workers. On failure the results stored
    so far stay, the session keeps its status and the error propagates. :meth:`Session.request_stop`
    ends it after the running step (:class:`~mirrorlab.core.errors.StoppedOnRequest`).
    """
    digest = hashlib.sha256((recipe.text + json.dumps(recipe.overrides)).encode()).hexdigest()
    with Session.open(path, writable=True, registry=registry) as session:
        session.executor = executor
        if on_session is not None:
            on_session(session)
        session.events.emit("info", "recipe", "analysis", f"analysis recipe {recipe.path.name}",
                            path=str(recipe.path), recipe_hash=f"sha256:{digest}", overrides=recipe.overrides,
                            executor=getattr(executor, "provenance", None))
        check_on_session(recipe, session)
        with session.operation():
            for step in recipe.steps:
                session.events.emit("info", "recipe", "step", f"step {step.index}: {step.action}")
                try:
                    step.cls().execute(session, step.values)
                except MirrorlabError:
                    if not session.stop_requested:
                        raise
                if session.stop_requested:
                    raise StoppedOnRequest(f"stopped on request during step {step.index} ({step.action}); "
                                           f"the results stored so far stay in {path}")
    return path
