"""``mirrorlab run`` (a recipe) and ``mirrorlab demo`` (the bundled main job)."""

from __future__ import annotations

import argparse
import signal
import sys
import threading
from importlib import resources
from pathlib import Path

from ..recipes import load_recipe, run_recipe
from ..session import Session
from .outputs import add_overwrite_option, cli_advice
from .progress import progress_bar

#: The recipe ``mirrorlab demo`` runs: package data of ``mirrorlab.sessions`` (``sessions/`` in a checkout).
DEMO_RECIPE = Path(str(resources.files("mirrorlab.sessions") / "rssr_mirror.toml"))
#: Where ``mirrorlab demo`` writes without ``--out``, relative to the current folder.
DEMO_OUTPUT = Path("sessions") / "out"


def _plural(n: int, word: str) -> str:
    return f"{n} {word}{'' if n == 1 else 's'}"


def _common(p: argparse.ArgumentParser, out_help: str) -> None:
    p.add_argument("--out", type=Path, metavar="FILE.h5", help=out_help)
    add_overwrite_option(p)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a recipe value, e.g. steps.0.seconds=2 (repeatable)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="validate and run a recipe (TOML) into a new session file")
    p.add_argument("recipe", type=Path, help="recipe file (TOML), e.g. sessions/scan_film.toml")
    _common(p, "session file to write (default: out/<recipe>-<UTC time>.h5 in the recipe's folder)")
    p.add_argument("--check", action="store_true", help="only validate the recipe")
    p.set_defaults(func=run)
    d = sub.add_parser("demo", help="run the bundled demonstration recipe on simulated instruments",
                       description=f"Run the RSSR mirror experiment recipe that comes with mirrorlab ({DEMO_RECIPE.name}, "
                                   "see docs/demo.md) on simulated instruments, from any folder.")
    _common(d, f"session file to write (default: {DEMO_OUTPUT}/rssr_mirror-<UTC time>.h5 in the current folder)")
    d.set_defaults(func=demo, check=False)


def run(args: argparse.Namespace) -> int:
    recipe = load_recipe(args.recipe, args.overrides)
    if args.check:
        print(f"{args.recipe}: ok ({_plural(len(recipe.instruments), 'instrument')}, "
              f"{_plural(len(recipe.steps), 'step')})")
        return 0
    out = args.out or recipe.default_output(getattr(args, "default_root", None))

    def on_session(session: Session) -> None:
        session.events.subscribe(on_event)
        stop_on_interrupt(session)

    try:
        with cli_advice("--out"), progress_bar(not args.no_progress) as on_event:
            run_recipe(recipe, out, on_session=on_session, overwrite=args.overwrite)
    finally:
        if threading.current_thread() is threading.main_thread():
            signal.signal(signal.SIGINT, signal.default_int_handler)
    print_summary(out)
    return 0


def stop_on_interrupt(session: Session) -> None:
    """First Ctrl-C: ask the session to stop cleanly (the step ends, the file closes, the reason is
    logged); a second one interrupts at once (the file is closed as aborted)."""
    def first(signum: int, frame: object) -> None:
        signal.signal(signal.SIGINT, signal.default_int_handler)
        print("\nmirrorlab: stopping after the current step's work ends (Ctrl-C again to abort)", file=sys.stderr)
        session.request_stop()

    if threading.current_thread() is threading.main_thread():  # signals reach the main thread only
        signal.signal(signal.SIGINT, first)


def demo(args: argparse.Namespace) -> int:
    args.recipe, args.default_root = DEMO_RECIPE, Path.cwd() / DEMO_OUTPUT
    return run(args)


def print_summary(path: Path) -> None:
    with Session.open(path) as s:
        info = s.describe()
    print(f"session {info['attributes']['session_id']} [{info['attributes']['status']}] -> {path}")
    for label, inst in [*info["instruments"].items(), *info["controllers"].items()]:
        for name, st in inst["streams"].items():
            shape = "x".join(map(str, st["shape"])) or "scalar"
            print(f"  {label}/{name}: {st['samples']} samples of {shape} {st['dtype']} {st['unit']}")
    for r in info["results"]:
        print(f"  {r['path']}: {r['status']} {r['error']}")
