"""``mirrorlab plugins``: list, inspect and diagnose plugins."""

from __future__ import annotations

import argparse
import json
from typing import TYPE_CHECKING, Any, cast

from ..errors import Problem, ValidationError
from ..registry import KINDS, get_registry
from .options import parameter_facts, plain

if TYPE_CHECKING:
    from ..devices import Instrument


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("plugins", help="list installed plugins, instruments, algorithms and steps")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=list_plugins)
    psub = p.add_subparsers(dest="plugins_command", metavar="SUBCOMMAND")
    d = psub.add_parser("doctor", help="entry points, import errors, hook validation, simulators, versions")
    # SUPPRESS: `plugins --json doctor` and `plugins doctor --json` both count
    d.add_argument("--json", action="store_true", default=argparse.SUPPRESS, help="machine-readable output")
    d.set_defaults(func=doctor)
    s = psub.add_parser("show", help="one instrument, algorithm, controller or step with its typed parameters "
                                     "(every kind that has the name, unless --kind picks one)")
    s.add_argument("name", help="instrument, algorithm, controller or step name (mirrorlab plugins lists them)")
    s.add_argument("--kind", choices=KINDS, help="show only this kind (several kinds may share a name)")
    s.add_argument("--json", action="store_true", default=argparse.SUPPRESS, help="machine-readable output")
    s.set_defaults(func=show)


def _describe(kind: str, cls: Any) -> dict[str, Any]:
    if hasattr(cls, "describe") and kind == "algorithm":
        return cls.describe()
    out = {"name": cls.name, "version": cls.version, "description": cls.description,
           "parameters": cls.parameters.describe()}
    if kind == "instrument":
        out["simulator"] = cls.has_simulator()
    if kind == "step":
        out["tables"] = dict(cls.tables)
    return out


def inventory() -> dict[str, Any]:
    reg = get_registry()
    out: dict[str, Any] = {}
    for kind in KINDS:
        items = []
        for name in reg.names(kind):
            providers = reg.providers(kind, name)
            for prov in providers:
                entry = _describe(kind, prov.cls)
                entry["plugin"] = prov.plugin
                items.append(entry)
        out[kind + "s"] = items
    out["plugins"] = [{"name": p.name, "source": p.source, "distribution": p.distribution, "version": p.version,
                       "ok": p.ok, "error": p.error, "provides": p.provides} for p in reg.plugins.values()]
    out["conflicts"] = reg.conflicts()
    return out


def list_plugins(args: argparse.Namespace) -> int:
    data = inventory()
    if args.json:
        print(json.dumps(data, indent=2, default=str))
        return 0
    for kind in KINDS:
        print(f"{kind}s:")
        for item in data[kind + "s"]:
            print(f"  {item['name']:<22} {item['version']:<8} {item['description']}  [{item['plugin']}]")
        if not data[kind + "s"]:
            print("  (none)")
    broken = [p for p in data["plugins"] if not p["ok"]]
    if broken or data["conflicts"]:
        print("problems (details: mirrorlab plugins doctor):")
        for p in broken:
            print(f"  BROKEN {p['name']}: {p['error']}")
        for c in data["conflicts"]:
            print(f"  CONFLICT {c}")
    return 0


def simulator_problem(cls: Any) -> str:
    """Why an instrument cannot be simulated though its default settings need a device port, or ``""``."""
    if cls.has_simulator() or not cls.needs_port(cls.parameters.defaults()):
        return ""
    return (f"instrument {cls.name!r} needs a port but cannot make a simulator: set `simulator` or override "
            "`make_simulator` (recipes with simulate = true and the conformance kit need one)")


def doctor(args: argparse.Namespace) -> int:
    reg = get_registry()
    rows: list[dict[str, Any]] = []
    declarations = reg.undeclared()  # a name a plugin provides but does not declare is found only by listing
    for p in reg.plugins.values():
        simulators, problems = {}, [m for m in declarations if m.startswith(f"plugin {p.name!r} ")]
        for name in p.provides.get("instrument", []):
            cls = cast("type[Instrument]", reg.providers("instrument", name)[0].cls)  # the first, even of a conflict
            simulators[name] = cls.has_simulator()
            problems += [m for m in [simulator_problem(cls)] if m]
        rows.append({"name": p.name, "entry_point": p.source, "distribution": p.distribution,
                     "version": p.version, "ok": p.ok, "error": p.error, "traceback": p.traceback,
                     "provides": p.provides, "simulators": simulators, "problems": problems})
    conflicts = reg.conflicts()
    if args.json:
        print(json.dumps({"plugins": rows, "conflicts": conflicts}, indent=2))
    else:
        for r in rows:
            state = "ok" if r["ok"] and not r["problems"] else "BROKEN" if not r["ok"] else "PROBLEM"
            print(f"{r['name']} [{state}]  entry point: {r['entry_point']}"
                  + (f"  ({r['distribution']} {r['version']})" if r["distribution"] else ""))
            for kind, names in r["provides"].items():
                print(f"    {kind}s: {', '.join(names)}")
            for name, has in r["simulators"].items():
                print(f"    simulator for {name}: {'yes' if has else 'no'}")
            for problem in r["problems"]:
                print(f"    problem: {problem}")
            if not r["ok"]:
                print(f"    error: {r['error']}")
                print("    " + r["traceback"].rstrip().replace("\n", "\n    "))
        for c in conflicts:
            print(f"CONFLICT: {c}")
    return 1 if conflicts or any(not r["ok"] or r["problems"] for r in rows) else 0


def show(args: argparse.Namespace) -> int:
    reg = get_registry()
    kinds = [k for k in KINDS if reg.providers(k, args.name) and args.kind in (None, k)]
    if not kinds:
        what = f"no {args.kind}" if args.kind else "nothing"
        raise ValidationError([Problem("", f"{what} named {args.name!r}; `mirrorlab plugins` lists what is installed")])
    if args.json:  # one object, of the first kind when --kind does not pick one
        print(json.dumps(_describe(kinds[0], reg.get(kinds[0], args.name)), indent=2, default=str))
        return 0
    for i, kind in enumerate(kinds):
        if i:
            print()
        _print_plugin(kind, _describe(kind, reg.get(kind, args.name)))
    return 0


def _print_plugin(kind: str, info: dict[str, Any]) -> None:
    print(f"{kind} {info['name']} {info['version']}: {plain(info['description'])}")
    if info["parameters"]:
        print("  parameters:" if kind == "algorithm" else "  settings:" if kind in ("instrument", "controller") else "  keys:")
    for p in info["parameters"]:  # name, type, unit, bounds, choices, default; the help on its own line
        unit = f"[{p['unit']}]" if p["unit"] else ""
        print(f"    {p['name']:<20} {p['type']:<6} {unit:<8} {'; '.join(parameter_facts(p))}")
        print(f"    {'':<20} {plain(p['help'])}")
    for title, key in (("tables", "tables"), ("inputs", "inputs"), ("outputs", "outputs")):
        rows = info.get(key) or {}
        if rows:
            print(f"  {title}:")
        items = rows.items() if isinstance(rows, dict) else ((r["name"], r["description"]) for r in rows)
        for name, text in items:
            print(f"    {name:<20} {plain(text)}")
