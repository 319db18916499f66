"""``mirrorlab tui [RECIPE.toml | SESSION.h5]``: the operator console (Textual, in the terminal)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from ..errors import SessionError
from .options import existing_path
from .outputs import add_allow_port_url_option, add_overwrite_option, cli_advice
from .run_cmd import DEMO_ACQUIRE, DEMO_OUTPUT, on_stop_signals, print_summary, restore_interrupt

#: Suffixes of session files (anything else is read as a recipe).
SESSION_SUFFIXES = (".h5", ".hdf5")


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("tui", help="the operator console: live dashboard, recording, set-points, in the terminal",
                       description="Open a recipe (its instruments connected, nothing recorded until you press r) or "
                                   "a session file (browsing) in the operator console. Without a file, the bundled "
                                   f"demonstration recipe ({DEMO_ACQUIRE.name}). Keys: ? help, p preview, r record, "
                                   "s stop, t steps, a analysis, b browse, g plots, c camera, enter details, d light/dark, "
                                   "ctrl+p every action, ctrl+q quit.")
    p.add_argument("file", type=existing_path, nargs="?", metavar="RECIPE.toml | SESSION.h5",
                   help="recipe to open live, or session file to browse (default: the demonstration recipe)")
    p.add_argument("--out", type=Path, metavar="FILE.h5",
                   help="session file a recipe records into (default: out/<recipe>-<UTC time>.h5 in the recipe's folder)")
    add_overwrite_option(p, also="; also replace the files the recipe writes (figures, CSV)")
    add_allow_port_url_option(p)
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                   help="override a recipe value, e.g. instruments.sensor.settings.rate=50 (repeatable)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from ..tui.app import MirrorlabApp
    from ..tui.model import Console

    path: Path | None = args.file
    if path is not None and path.suffix.lower() in SESSION_SUFFIXES:
        console = Console.from_file(path)
    else:
        root = Path.cwd() / DEMO_OUTPUT if path is None else None  # the demo writes under ./sessions/out
        with cli_advice("--out"):
            console = Console.from_recipe(path or DEMO_ACQUIRE, args.out, args.overrides, args.overwrite, root,
                                          allow_port_url=args.allow_port_url)
    if not args.debug:  # the log pane shows the session's events; a stray log line would tear the screen
        logging.getLogger("mirrorlab").setLevel(logging.CRITICAL)
    app = MirrorlabApp(console)
    on_stop_signals(app.quit_on_signal)  # SIGTERM, SIGHUP: quit as ctrl+q does (Ctrl-C is a key in the console)
    try:
        code = app.run()
    finally:
        restore_interrupt()
        console.close()  # idempotent: ctrl+q already closed it; any other exit closes it here
    if app.close_error:
        raise SessionError(f"{app.close_error}; the session file {console.session.path} was closed aborted")
    if console.session.path.exists():  # a new session closed before it held anything leaves no file
        print_summary(console.session.path)
    return code or 0
