"""``mirrorlab simulate INSTRUMENT``: serve an instrument's simulator for other programs to talk to.

A lab uses it to test its own client, or firmware against the documented protocol: the simulator
speaks exactly what the instrument's driver expects, on a pseudo-terminal or a TCP port, until
interrupted (Ctrl-C, or SIGTERM as a service manager sends). The first line printed names the address.
"""

from __future__ import annotations

import argparse
import signal
import sys
import threading
import time
import tomllib
from pathlib import Path
from typing import Any

from ..errors import PluginError, Problem, ValidationError
from ..registry import get_registry

DESCRIPTION = (
    "Serve the simulator of a serial instrument (the one its driver is tested against) on a "
    "pseudo-terminal or a TCP port until interrupted, so that another program can talk to it. "
    "The first line printed is the address: a path to open as a serial port, or socket://HOST:PORT."
)


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="serve an instrument's simulator on a pty or TCP port",
                       description=DESCRIPTION)
    p.add_argument("instrument", help="registered instrument plugin, e.g. film_scanner (mirrorlab plugins lists them)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--tcp", type=int, metavar="PORT",
                       help="listen on 127.0.0.1:PORT (0 picks a free port) instead of a pseudo-terminal")
    where.add_argument("--pty", type=Path, metavar="PATH",
                       help="link the pseudo-terminal at PATH (default: a temporary path)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulator's random generator (default 0)")
    p.add_argument("--clock", choices=("fast", "real"), default="real",
                   help="real: modelled timing in real time (default); fast: as fast as possible")
    p.add_argument("--set", dest="settings", action="append", default=[], metavar="KEY=VALUE",
                   help="an instrument setting the simulator is made for, e.g. scene_frames=100 (repeatable)")
    p.add_argument("--for", dest="seconds", type=float, metavar="SECONDS",
                   help="stop after SECONDS (default: until interrupted with Ctrl-C or SIGTERM)")
    p.set_defaults(func=simulate)


def _settings(pairs: list[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for pair in pairs:
        key, sep, raw = pair.partition("=")
        if not sep or not key.strip():
            raise ValidationError([Problem("--set", f"{pair!r} is not KEY=VALUE (e.g. scene_frames=100)")])
        try:
            out[key.strip()] = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            out[key.strip()] = raw
    return out


def simulate(args: argparse.Namespace) -> int:
    from ..devices import SimulatorServer

    try:
        cls = get_registry().instrument(args.instrument)
    except PluginError as exc:
        raise ValidationError([Problem("INSTRUMENT", str(exc))]) from None
    settings = cls.parameters.validate(_settings(args.settings), where="--set")
    if not cls.needs_port(settings):
        raise ValidationError([Problem("--set", f"{cls.name} with these settings is no serial device (a file, "
                                       "camera or virtual source is its own simulation); there is nothing to serve")])
    model = cls.make_simulator(settings, args.seed)  # PluginError if the plugin ships none
    if args.pty is not None and not args.pty.parent.is_dir():
        raise ValidationError([Problem("--pty", f"folder {args.pty.parent} does not exist; give a path in an "
                                       "existing folder (the pseudo-terminal is linked there)")])
    model.fast = args.clock == "fast"
    transport = "tcp" if args.tcp is not None else "pty"
    with SimulatorServer(model, transport, link=args.pty, port=args.tcp or 0) as server:
        print(server.url, flush=True)
        until = "stop with Ctrl-C" if args.seconds is None else f"stops after {args.seconds:g} s (or Ctrl-C)"
        print(f"mirrorlab: serving the {cls.name} simulator ({model.kind}, seed {args.seed}, {args.clock} clock); "
              f"{until}", file=sys.stderr, flush=True)
        done = threading.Event()
        # Ctrl-C (SIGINT) and SIGTERM both stop it cleanly; SIGINT is handled here even where it was
        # inherited as ignored (a simulator started from a background job), as it is sent on purpose.
        previous = {sig: signal.signal(sig, lambda signum, frame: done.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
        try:
            deadline = None if args.seconds is None else time.monotonic() + args.seconds
            while not done.wait(0.2 if deadline is None else max(0.0, min(0.2, deadline - time.monotonic()))):
                if deadline is not None and time.monotonic() >= deadline:
                    break
        finally:
            for sig, handler in previous.items():
                signal.signal(sig, handler)
        if done.is_set():
            print("mirrorlab: simulator stopped", file=sys.stderr)
    return 0
