"""``mirrorlab run`` (a recipe, or an analysis recipe on an existing session) and ``mirrorlab demo``."""

from __future__ import annotations

import argparse
import contextlib
import signal
import sys
import threading
from collections.abc import Callable
from contextlib import ExitStack
from importlib import resources
from pathlib import Path
from typing import Any

from ..batch.options import add_cluster_options, positive_int
from ..errors import Problem, ValidationError
from ..recipes import Recipe, check_outputs, load_recipe, run_analysis, run_recipe
from ..session import Session
from ..store.integrity import instrument_failures
from .options import existing_path
from .outputs import (
    add_allow_empty_option,
    add_allow_port_url_option,
    add_overwrite_option,
    cli_advice,
    escaped,
    group_contents,
    plural,
)
from .progress import progress_bar

_BUNDLED = resources.files("mirrorlab.sessions")
#: The recipes ``mirrorlab demo`` runs, one after the other on one session: package data of
#: ``mirrorlab.sessions`` (``sessions/`` in a checkout).
DEMO_ACQUIRE = Path(str(_BUNDLED / "rssr_acquire.toml"))
DEMO_ANALYSIS = Path(str(_BUNDLED / "rssr_analysis.toml"))
#: Where ``mirrorlab demo`` writes without ``--out``, relative to the current folder, and the file's stem.
DEMO_OUTPUT = Path("sessions") / "out"
DEMO_NAME = "rssr_mirror"
#: The ``--set`` example of ``mirrorlab demo --help``: a shorter film (6 of 33 frames) of the recording recipe.
DEMO_EXAMPLE = "instruments.rssr.settings.scene_frames=6"


def _common(p: argparse.ArgumentParser, out_help: str, example: str) -> None:
    p.add_argument("--out", type=Path, metavar="FILE.h5", help=out_help)
    add_overwrite_option(p, also="; also replace the files the recipe writes (figures, CSV), with --session too")
    add_allow_port_url_option(p)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help=f"override a recipe value, e.g. {example} (repeatable)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_allow_empty_option(p)


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="validate and run a recipe (TOML) into a new session file",
                       description="Run a recipe into a new session file, or with --session an analysis recipe "
                                   "(no instruments, no acquire step) on an existing session, appending results.")
    p.add_argument("recipe", type=Path, help="recipe file (TOML), e.g. sessions/scan_film.toml")
    _common(p, "session file to write (default: out/<recipe>-<UTC time>.h5 in the recipe's folder)",
            "steps.0.seconds=2")
    p.add_argument("--check", action="store_true", help="only validate the recipe")
    p.add_argument("--session", type=existing_path, metavar="FILE.h5",
                   help="run an analysis recipe on this existing session, appending its results")
    cluster = p.add_argument_group("chunks of frames on Dask workers (with --session)")
    add_cluster_options(cluster)
    cluster.add_argument("--chunk-frames", type=positive_int, default=None, metavar="N",
                         help="frames per chunk of frame-wise steps (detection; default 1000)")
    p.set_defaults(func=run)
    d = sub.add_parser("demo", help="run the bundled demonstration recipe on simulated instruments",
                       description=f"Run the RSSR mirror experiment that comes with mirrorlab ({DEMO_ACQUIRE.name}, "
                                   f"then {DEMO_ANALYSIS.name} on its session; see docs/demo.md) on simulated "
                                   "instruments, from any folder. --set steps.N... overrides the analysis recipe, "
                                   "other keys the recording one.")
    _common(d, f"session file to write (default: {DEMO_OUTPUT}/{DEMO_NAME}-<UTC time>.h5 in the current folder)",
            DEMO_EXAMPLE)
    d.set_defaults(func=demo, check=False)


def run(args: argparse.Namespace) -> int:
    analysis = getattr(args, "session", None) is not None
    recipe = load_recipe(args.recipe, args.overrides, analysis=analysis, allow_port_url=args.allow_port_url)
    out = args.session if analysis else args.out or recipe.default_output(getattr(args, "default_root", None))
    check_outputs(recipe, out, args.overwrite)
    if args.check:
        print(f"{args.recipe}: ok ({plural(len(recipe.instruments), 'instrument')}, "
              f"{plural(len(recipe.steps), 'step')})")
        return 0
    if analysis:
        return _run_on_session(args, recipe)
    if args.workers or args.scheduler or args.chunk_frames:
        raise ValidationError([Problem("--workers", "--workers, --scheduler and --chunk-frames go with --session "
                                       "(an analysis on an existing session)")])

    def on_session(session: Session) -> None:
        session.events.subscribe(on_event)
        stop_on_interrupt(session)

    try:
        with cli_advice("--out"), progress_bar(not args.no_progress) as on_event:
            run_recipe(recipe, out, on_session=on_session, overwrite=args.overwrite)
    finally:
        restore_interrupt()
    return print_summary(out, args.allow_empty)


#: What stops ``run``, ``demo``, ``record`` and ``tui`` as the first Ctrl-C does: Ctrl-C (SIGINT),
#: ``kill``, ``timeout`` or systemd (SIGTERM), and a closed terminal or SSH session (SIGHUP).
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
#: The handlers :func:`stop_on_interrupt` replaced, put back by :func:`restore_interrupt`.
_replaced: dict[int, Any] = {}


def on_stop_signals(stop: Callable[[str], None]) -> None:
    """Call ``stop(name)`` on the first of :data:`STOP_SIGNALS` (``name``: ``Ctrl-C``, ``SIGTERM``...); any
    second one raises :class:`KeyboardInterrupt` (abort at once). SIGTERM or SIGHUP ignored when the command
    started stays ignored (``nohup`` keeps SIGHUP away); SIGINT is handled all the same, as the simulators
    do: a shell starts background jobs with it ignored (``cmd &`` in a script), yet ``kill -INT`` is sent on
    purpose. :func:`restore_interrupt` puts the handlers back."""
    def second(signum: int, frame: object) -> None:
        raise KeyboardInterrupt

    def first(signum: int, frame: object) -> None:
        for sig in _replaced:
            signal.signal(sig, second)
        stop("Ctrl-C" if signum == signal.SIGINT else signal.Signals(signum).name)

    if threading.current_thread() is not threading.main_thread():  # signals reach the main thread only
        return
    for sig in STOP_SIGNALS:
        if sig not in _replaced:  # else installed for an earlier session of this command: the original is kept
            previous = signal.getsignal(sig)
            if previous is signal.SIG_IGN and sig != signal.SIGINT:
                continue
            _replaced[sig] = previous
        signal.signal(sig, first)


def stop_on_interrupt(session: Session) -> None:
    """First Ctrl-C, SIGTERM or SIGHUP: ask the session to stop cleanly (the step ends, the file closes,
    the reason is logged); a second one interrupts at once (the file is closed as aborted)."""
    def stop(name: str) -> None:
        with contextlib.suppress(OSError):  # after SIGHUP the terminal may be gone
            print(f"\nmirrorlab: {name}: stopping after the current step's work ends (Ctrl-C again to abort)",
                  file=sys.stderr)
        session.request_stop()

    on_stop_signals(stop)


def restore_interrupt() -> None:
    """Put back the handlers :func:`on_stop_signals` replaced (Ctrl-C raises KeyboardInterrupt again)."""
    if threading.current_thread() is threading.main_thread():
        for sig, handler in _replaced.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)
        _replaced.clear()


def _run_on_session(args: argparse.Namespace, recipe: Recipe) -> int:
    if args.out:
        raise ValidationError([Problem("--session", "appends to that file: --out does not apply")])
    with ExitStack() as stack:
        executor = None
        if args.workers or args.scheduler:
            from ..batch.cluster import dask_client, describe
            from ..batch.executors import CHUNK_FRAMES, ChunkedExecutor

            client = stack.enter_context(dask_client(args.workers, args.scheduler))
            executor = ChunkedExecutor(client, {**describe(client), "mode": "chunked frames"},
                                       args.chunk_frames or CHUNK_FRAMES)
        on_event = stack.enter_context(progress_bar(not args.no_progress))
        stack.callback(restore_interrupt)

        def on_session(session: Session) -> None:
            session.events.subscribe(on_event)
            stop_on_interrupt(session)

        run_analysis(recipe, args.session, on_session=on_session, executor=executor)
    print_summary(args.session)
    return 0


def demo(args: argparse.Namespace) -> int:
    """The recording recipe into a new session, then the analysis recipe on it: one session file."""
    analysis_overrides = [o for o in args.overrides if o.startswith("steps.")]
    acquire = load_recipe(DEMO_ACQUIRE, [o for o in args.overrides if o not in analysis_overrides],
                          allow_port_url=args.allow_port_url)
    analysis = load_recipe(DEMO_ANALYSIS, analysis_overrides, analysis=True)
    default = acquire.default_output(Path.cwd() / DEMO_OUTPUT)
    out = args.out or default.with_name(default.name.replace(DEMO_ACQUIRE.stem, DEMO_NAME, 1))
    for recipe in (acquire, analysis):
        check_outputs(recipe, out, args.overwrite)
    try:
        with cli_advice("--out"), progress_bar(not args.no_progress) as on_event:
            def subscribe(session: Session) -> None:
                session.events.subscribe(on_event)
                stop_on_interrupt(session)

            run_recipe(acquire, out, on_session=subscribe, overwrite=args.overwrite)
            run_analysis(analysis, out, on_session=subscribe)
    finally:
        restore_interrupt()
    return print_summary(out, args.allow_empty)


def print_summary(path: Path, allow_empty: bool | None = None) -> int:
    """Print what the session holds; return the exit code. After a recording (``allow_empty`` not
    ``None``) an instrument that failed while recording (its reconnect budget spent) is an error (1),
    and so is one that recorded no sample at all (its source delivered nothing), or with
    ``allow_empty`` a warning (0)."""
    with Session.open(path) as s:
        info = escaped(s.describe())  # a file from elsewhere (--session) may hold terminal escapes
        failures = [] if allow_empty is None else instrument_failures(s.log())
    print(f"session {info['attributes']['session_id']} [{info['attributes']['status']}] -> {path}")
    for label, inst in [*info["instruments"].items(), *info["controllers"].items()]:
        for name, st in inst["streams"].items():
            shape = "x".join(map(str, st["shape"])) or "scalar"
            print(f"  {label}/{name}: {st['samples']} samples of {shape} {st['dtype']} {st['unit']}")
    for group, g in info["groups"].items():
        print(f"  {group}: {group_contents(g)}")
    for r in info["results"]:
        print(f"  {r['path']}: {r['status']} {r['error']}")
    for failure in failures:  # the recording went on without it: what it recorded is kept, the rest missing
        print(f"mirrorlab: error: {failure}; {path} keeps what it recorded before", file=sys.stderr)
    empty = [label for label, inst in info["instruments"].items()
             if inst["streams"] and not any(st["samples"] for st in inst["streams"].values())]
    if allow_empty is None or not empty:
        return 1 if failures else 0
    message = (f"{', '.join(empty)} recorded no sample: the source delivered nothing in the time recorded (e.g. a "
               f"real-clock film scanner takes seconds per frame: record longer); {path} keeps the empty recording")
    print(f"mirrorlab: warning: {message}" if allow_empty else
          f"mirrorlab: error: {message}; add --allow-empty to accept an empty recording", file=sys.stderr)
    return 0 if allow_empty and not failures else 1
