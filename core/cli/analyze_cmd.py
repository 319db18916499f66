"""``mirrorlab analyze ALGORITHM SESSION`` and ``mirrorlab record INSTRUMENT``: options from parameters."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..errors import Problem, ValidationError
from ..registry import get_registry
from ..session import Session
from ..steps import Acquire
from .options import add_parameter_options, collected
from .outputs import add_overwrite_option, cli_advice
from .progress import progress_bar
from .run_cmd import print_summary

#: ``mirrorlab record --seconds`` when not given, s.
RECORD_SECONDS = 5.0


def duration(text: str) -> float:
    """``--seconds``: checked like the recipe step ``acquire``'s ``seconds`` (units, >= 0; 0 = until the end)."""
    value, reason = Acquire.parameters["seconds"].check(text)
    if reason:
        raise argparse.ArgumentTypeError(reason)
    return float(value)


def add(sub: argparse._SubParsersAction) -> None:
    reg = get_registry()
    a = sub.add_parser("analyze", help="run a registered algorithm on datasets of a session")
    asub = a.add_subparsers(dest="algorithm", metavar="ALGORITHM", required=True)
    for name in reg.names("algorithm"):
        try:
            cls = reg.algorithm(name)
        except Exception:  # a conflicting name: reported by `plugins doctor`, not offered here
            continue
        p = asub.add_parser(name, help=cls.description, description=cls.description)
        p.add_argument("session", type=Path, help="session file (results are added to it)")
        ins = ", ".join(f"{i.name} ({i.description})" for i in cls.inputs)
        p.add_argument("--input", action="append", default=[], metavar="NAME=/DATASET",
                       help=f"input dataset paths; inputs: {ins or 'none'}")
        p.add_argument("--no-progress", action="store_true")
        add_parameter_options(p, cls.parameters)
        p.set_defaults(func=analyze, algorithm_name=name)

    r = sub.add_parser("record", help="record one instrument (real or simulated) into a new session")
    rsub = r.add_subparsers(dest="instrument", metavar="INSTRUMENT", required=True)
    for name in reg.names("instrument"):
        try:
            cls = reg.instrument(name)
        except Exception:
            continue
        p = rsub.add_parser(name, help=cls.description, description=cls.description)
        p.add_argument("--out", type=Path, required=True, help="session file to create")
        add_overwrite_option(p)
        p.add_argument("--seconds", type=duration, default=RECORD_SECONDS, metavar="S",
                       help=f"how long to record [s] (default {RECORD_SECONDS:g}; 0 = until every source has "
                            "ended, as in a recipe's acquire step; Ctrl-C stops an endless source)")
        p.add_argument("--port", help="device path or pyserial URL")
        p.add_argument("--simulate", action="store_true", help="use the plugin's simulator")
        p.add_argument("--fast", action="store_true", help="simulator clock FAST instead of REAL")
        p.add_argument("--no-progress", action="store_true")
        add_parameter_options(p, cls.parameters)
        p.set_defaults(func=record, instrument_name=name)


def analyze(args: argparse.Namespace) -> int:
    inputs = {}
    for item in args.input:
        name, sep, path = item.partition("=")
        if not sep:
            raise ValidationError([Problem("--input", f"{item!r} is not NAME=/DATASET")])
        inputs[name] = path
    with Session.open(args.session, writable=True) as s, progress_bar(not args.no_progress) as on_event:
        s.events.subscribe(on_event)
        ref = s.run(args.algorithm_name, inputs, collected(args))
    print(f"{ref.path}: {ref.status}{' — ' + ref.error if ref.error else ''}")
    return 0 if ref.status == "ok" else 1


def record(args: argparse.Namespace) -> int:
    with cli_advice("--out"), progress_bar(not args.no_progress) as on_event:
        with Session.create(args.out, description=f"mirrorlab record {args.instrument_name}",
                            overwrite=args.overwrite) as s:
            s.events.subscribe(on_event)
            s.add_instrument("dev", args.instrument_name, port=args.port, settings=collected(args),
                             simulate=args.simulate, simulator={"clock": "FAST" if args.fast else "REAL"})
            s.record(args.seconds)
            failed = [label for label, inst in s.instruments.items() if inst.failed is not None]
    asked = (f"of the requested {args.seconds:g} s (--seconds)" if args.seconds
             else "until the source ended (--seconds 0)")
    print(f"recorded {s.recorded_seconds:.1f} s {asked}")
    print_summary(args.out)
    return 1 if failed else 0
