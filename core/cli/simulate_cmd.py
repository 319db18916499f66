"""``mirrorlab simulate INSTRUMENT``: serve an instrument's simulator for other programs to talk to.

A lab uses it to test its own client, or firmware against the documented protocol: the simulator
speaks exactly what the instrument's driver expects, on a pseudo-terminal or a TCP port, until
interrupted (Ctrl-C, or SIGTERM as a service manager sends). The first line printed names the address.
TCP listens on the loopback interface unless ``--tcp HOST:PORT`` names another (with a warning: the
protocol has no authentication); ``--baud N`` paces the output as a real serial line of N baud would
(``docs/instruments/connecting.md``).
"""

from __future__ import annotations

import argparse
import ipaddress
import signal
import sys
import threading
import time
import tomllib
from pathlib import Path
from typing import Any

from ..errors import ConfigurationError, PluginError, Problem, ValidationError
from ..registry import get_registry

DESCRIPTION = (
    "Serve the simulator of a serial instrument (the one its driver is tested against) on a "
    "pseudo-terminal or a TCP port until interrupted, so that another program can talk to it. "
    "The first line printed is the address: a path to open as a serial port, or socket://HOST:PORT. "
    "One client is served at a time; docs/instruments/connecting.md describes the line protocol."
)
#: The real line's default speed, baud (``instruments.md`` §0.2).
LINE_BAUD = 115200


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("simulate", help="serve an instrument's simulator on a pty or TCP port",
                       description=DESCRIPTION)
    p.add_argument("instrument", help="registered instrument plugin, e.g. film_scanner (mirrorlab plugins lists them)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--tcp", metavar="[HOST:]PORT",
                       help="listen on TCP PORT (0 picks a free port) instead of a pseudo-terminal, on 127.0.0.1 "
                            "unless HOST names another interface (0.0.0.0: every one; the protocol has no "
                            "authentication, so anyone who reaches the port commands the simulator)")
    where.add_argument("--pty", type=Path, metavar="PATH",
                       help="link the pseudo-terminal at PATH (default: a temporary path)")
    p.add_argument("--seed", type=int, default=0, help="seed of the simulator's random generator (default 0)")
    p.add_argument("--clock", choices=("fast", "real"), default="real",
                   help="real: modelled timing in real time (default); fast: as fast as possible")
    p.add_argument("--baud", type=int, metavar="N",
                   help=f"send no faster than a serial line of N baud, 8N1 (the devices' line: {LINE_BAUD}); "
                        "default: as fast as the client reads")
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


def _tcp_address(text: str) -> tuple[str, int]:
    """``(host, port)`` of ``--tcp [HOST:]PORT`` (the loopback interface without a host).

    >>> _tcp_address("5025"), _tcp_address("0.0.0.0:0"), _tcp_address("[::]:5025")
    (('127.0.0.1', 5025), ('0.0.0.0', 0), ('::', 5025))
    """
    host, _, port = text.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    if not port.isdigit() or int(port) > 65535:
        raise ValidationError([Problem("--tcp", f"{text!r} is not [HOST:]PORT with PORT 0...65535 "
                                                "(e.g. 5025, or 0.0.0.0:5025 to serve other machines)")])
    return host, int(port)


def _is_loopback(host: str) -> bool:
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return host == "localhost"


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
    if args.pty is not None:  # the link (and its temporary PATH.new) replaces what is there, and goes at exit
        taken = [p for p in (args.pty, args.pty.with_name(args.pty.name + ".new")) if p.exists() and not p.is_symlink()]
        if taken:
            raise ValidationError([Problem("--pty", f"{taken[0]} exists and is not a link: it would be replaced, "
                                           "then deleted at exit; give a new path (an old pty link is fine)")])
    if args.baud is not None and not 50 <= args.baud <= 10_000_000:
        raise ValidationError([Problem("--baud", f"{args.baud} is not a line speed; give 50...10000000 baud "
                                                 f"(the devices' line runs at {LINE_BAUD})")])
    host, port = _tcp_address(args.tcp) if args.tcp is not None else ("127.0.0.1", 0)
    model.fast = args.clock == "fast"
    transport = "tcp" if args.tcp is not None else "pty"
    try:
        server = SimulatorServer(model, transport, link=args.pty, host=host, port=port, baud=args.baud)
    except OSError as exc:
        raise ConfigurationError(f"cannot serve on {host}:{port} ({exc}); choose another port (0 picks a free "
                                 "one) or an address of this machine") from None
    done = threading.Event()
    # Ctrl-C (SIGINT) and SIGTERM both stop it cleanly; SIGINT is handled here even where it was
    # inherited as ignored (a simulator started from a background job), as it is sent on purpose.
    # Installed, and everything for stderr said, before the address is printed: a client that has
    # read the address may stop the simulator at once.
    previous = {sig: signal.signal(sig, lambda signum, frame: done.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        with server:
            if transport == "tcp" and not _is_loopback(host):
                print(f"mirrorlab: warning: listening on {server.url}, reachable from other machines; "
                      "the line protocol has no authentication: anyone who can connect can command the simulator",
                      file=sys.stderr, flush=True)
            until = "stop with Ctrl-C" if args.seconds is None else f"stops after {args.seconds:g} s (or Ctrl-C)"
            pace = "" if args.baud is None else f", paced to {args.baud} baud"
            print(f"mirrorlab: serving the {cls.name} simulator ({model.kind}, seed {args.seed}, {args.clock} clock"
                  f"{pace}); {until}", file=sys.stderr, flush=True)
            print(server.url, flush=True)
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
