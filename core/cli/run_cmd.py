"""``mirrorlab run`` (a recipe) and ``mirrorlab demo`` (the bundled main job)."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..recipes import load_recipe, run_recipe
from ..session import Session
from .outputs import add_overwrite_option, cli_advice
from .progress import progress_bar

#: The bundled recipe ``mirrorlab demo`` runs, relative to the repository/installation root.
DEMO_RECIPE = Path("sessions") / "rssr_mirror.toml"


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="validate and run a recipe (TOML) into a new session file")
    p.add_argument("recipe", type=Path)
    p.add_argument("--out", type=Path, help="session file to write (default sessions/out/<recipe>-<UTC>.h5)")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a recipe value, e.g. steps.0.seconds=2 (repeatable)")
    add_overwrite_option(p)
    p.add_argument("--check", action="store_true", help="only validate the recipe")
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=run)
    d = sub.add_parser("demo", help="run the bundled demonstration recipe on simulated instruments")
    d.add_argument("--out", type=Path)
    d.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    add_overwrite_option(d)
    d.add_argument("--no-progress", action="store_true")
    d.set_defaults(func=demo, check=False)


def run(args: argparse.Namespace) -> int:
    recipe = load_recipe(args.recipe, args.overrides)
    if args.check:
        print(f"{args.recipe}: ok ({len(recipe.instruments)} instruments, {len(recipe.steps)} steps)")
        return 0
    out = args.out or recipe.default_output()
    with cli_advice("--out"), progress_bar(not args.no_progress) as on_event:
        run_recipe(recipe, out, on_session=lambda s: s.events.subscribe(on_event), overwrite=args.overwrite)
    print_summary(out)
    return 0


def demo(args: argparse.Namespace) -> int:
    root = Path.cwd()
    recipe_path = root / DEMO_RECIPE
    if not recipe_path.exists():
        from ..errors import SessionError

        raise SessionError(f"the demo recipe {DEMO_RECIPE} is not here; run `mirrorlab demo` from the "
                           "root of a mirrorlab checkout")
    args.recipe = recipe_path
    return run(args)


def print_summary(path: Path) -> None:
    with Session.open(path) as s:
        info = s.describe()
    print(f"session {info['attributes']['session_id']} [{info['attributes']['status']}] -> {path}")
    for label, inst in info["instruments"].items():
        for name, st in inst["streams"].items():
            shape = "x".join(map(str, st["shape"])) or "scalar"
            print(f"  {label}/{name}: {st['samples']} samples of {shape} {st['dtype']} {st['unit']}")
    for r in info["results"]:
        print(f"  {r['path']}: {r['status']} {r['error']}")
