"""``mirrorlab analyze ALGORITHM SESSION`` and ``mirrorlab record INSTRUMENT``: options from parameters."""

from __future__ import annotations

import argparse
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from ..algorithms import Algorithm
from ..devices.transport import port_problem
from ..errors import Problem, StoppedOnRequest, ValidationError
from ..registry import get_registry
from ..session import Session
from ..steps import Acquire
from .commands import named_after
from .options import add_parameter_options, collected, existing_path
from .outputs import add_allow_empty_option, add_allow_port_url_option, add_overwrite_option, cli_advice
from .progress import progress_bar
from .run_cmd import print_summary, restore_interrupt, stop_on_interrupt

#: ``mirrorlab record --seconds`` when not given, s.
RECORD_SECONDS = 5.0


def duration(text: str) -> float:
    """``--seconds``: checked like the recipe step ``acquire``'s ``seconds`` (units, >= 0; 0 = until the end)."""
    value, reason = Acquire.parameters["seconds"].check(text)
    if reason:
        raise argparse.ArgumentTypeError(reason)
    return float(value)


def _built(names: list[str], argv: Sequence[str] | None, command: str) -> set[str]:
    """The sub-commands of ``command`` whose options parsing ``argv`` needs: none if ``argv`` runs another
    command, else the one it names, or all (the full help, ``--help``, a misspelt name)."""
    if argv is not None and command not in argv:
        return set()
    wanted = named_after(argv, command)
    return {wanted} if wanted in names else set(names)


def _named_parsers(sub: argparse._SubParsersAction, kind: str, argv: Sequence[str] | None,
                   command: str) -> Iterator[tuple[str, Any, argparse.ArgumentParser]]:
    """A sub-command of ``command`` per registered name of ``kind``: a bare name, unless parsing ``argv``
    needs its options (:func:`_built`); those are yielded as ``(name, class, parser)`` for their options."""
    reg = get_registry()
    names = reg.names(kind)
    built = _built(names, argv, command)
    for name in names:
        if name not in built:
            sub.add_parser(name, add_help=False)
            continue
        try:
            cls = reg.get(kind, name)
        except Exception:  # a conflicting name: reported by `plugins doctor`, not offered here
            continue
        yield name, cls, sub.add_parser(name, help=cls.description, description=cls.description)


def add(sub: argparse._SubParsersAction, argv: Sequence[str] | None = None) -> None:
    """Add ``analyze`` and ``record``; with ``argv`` naming an algorithm (instrument), only its options
    are built, so only the plugin providing it is imported (the others are names, never parsed)."""
    a = sub.add_parser("analyze", help="run a registered algorithm on datasets of a session")
    for name, cls, p in _named_parsers(a.add_subparsers(dest="algorithm", metavar="ALGORITHM", required=True),
                                       "algorithm", argv, "analyze"):
        p.add_argument("session", type=existing_path, help="session file (results are added to it)")
        ins = ", ".join(f"{i.name} ({i.description})" for i in cls.inputs)
        p.add_argument("--input", action="append", default=[], metavar="NAME=/DATASET",
                       help=f"input dataset paths; inputs: {ins or 'none'}")
        p.add_argument("--as", dest="label", metavar="LABEL",
                       help="run label: later inputs name this run's outputs @LABEL/OUTPUT (unique in the session)")
        p.add_argument("--no-progress", action="store_true", help="no progress bar")
        add_parameter_options(p, cls.parameters)
        p.set_defaults(func=analyze, algorithm_name=name)

    r = sub.add_parser("record", help="record one instrument (real or simulated) into a new session")
    for name, cls, p in _named_parsers(r.add_subparsers(dest="instrument", metavar="INSTRUMENT", required=True),
                                       "instrument", argv, "record"):
        p.add_argument("--out", type=Path, required=True, help="session file to create")
        add_overwrite_option(p)
        p.add_argument("--seconds", type=duration, default=RECORD_SECONDS, metavar="S",
                       help=f"how long to record [s] (default {RECORD_SECONDS:g}; 0 = until every source has "
                            "ended, as in a recipe's acquire step; Ctrl-C stops an endless source)")
        p.add_argument("--port", help="device path, socket://HOST:PORT, loop:// or rfc2217://HOST:PORT")
        add_allow_port_url_option(p)
        p.add_argument("--simulate", action="store_true", help="use the plugin's simulator")
        p.add_argument("--fast", action="store_true", help="simulator clock FAST instead of REAL")
        p.add_argument("--no-progress", action="store_true", help="no progress bar")
        add_allow_empty_option(p)
        add_parameter_options(p, cls.parameters)
        p.set_defaults(func=record, instrument_name=name)


def _checked(algorithm: type[Algorithm], args: argparse.Namespace) -> tuple[dict[str, str], dict[str, Any]]:
    """``--input NAME=/DATASET`` and ``--<parameter>`` options checked against the algorithm, named as options.

    Every problem is reported at once; a misspelt input name is not reported again as a missing input.
    """
    inputs, problems = {}, []
    ports = {p.name: p for p in algorithm.inputs}
    for item in args.input:
        name, sep, path = item.partition("=")
        if not sep or not path:
            problems.append(Problem("--input", f"{item!r} is not NAME=/DATASET"))
        elif name not in ports:
            problems.append(Problem(f"--input {name}", f"{algorithm.name} takes no input {name!r}; "
                                    f"it takes: {', '.join(ports) or 'none'}"))
        else:
            inputs[name] = path
    if not problems:
        problems = [Problem(f"--input {p.name}", f"required: {p.name}=/DATASET ({p.description})")
                    for p in algorithm.inputs if not p.optional and p.name not in inputs]
    params, more = algorithm.parameters.problems(collected(args))
    problems += [Problem("--" + p.key.replace("_", "-"), p.reason) for p in more]
    if problems:
        raise ValidationError(problems)
    return inputs, params


def analyze(args: argparse.Namespace) -> int:
    algorithm = get_registry().algorithm(args.algorithm_name)
    inputs, params = _checked(algorithm, args)
    with Session.open(args.session, writable=True) as s, progress_bar(not args.no_progress) as on_event:
        s.events.subscribe(on_event)
        ref = s.run(algorithm, inputs, params, label=args.label).require_ok()  # stored with its error; said once, by main()
        outputs = [s.node(f"{ref.path}/{name}") for name in s.members(ref.path)]
        written = {n.name: (n.shape, n.dtype, n.unit) for n in outputs if n.is_dataset}
    print(f"{args.session}: {ref.path}" + (f" (@{ref.label})" if ref.label else "") + ": ok")
    for name, (shape, dtype, unit) in written.items():
        print(f"  {ref.path}/{name}: {shape} {dtype}" + (f" [{unit}]" if unit else ""))
    return 0


def record(args: argparse.Namespace) -> int:
    if args.port and not args.allow_port_url and (reason := port_problem(args.port)):
        raise ValidationError([Problem("--port", reason)])
    try:
        with cli_advice("--out"), progress_bar(not args.no_progress) as on_event:
            with Session.create(args.out, description=f"mirrorlab record {args.instrument_name}",
                                overwrite=args.overwrite) as s:
                s.events.subscribe(on_event)
                stop_on_interrupt(s)
                with s.operation():  # a stop asked while the instrument connects ends the recording too
                    s.add_instrument("dev", args.instrument_name, port=args.port, settings=collected(args),
                                     simulate=args.simulate, simulator={"clock": "FAST" if args.fast else "REAL"})
                    s.record(args.seconds)
                failed = [label for label, inst in s.instruments.items() if inst.failed is not None]
                stopped = s.stop_requested
    finally:
        restore_interrupt()
    asked = (f"of the requested {args.seconds:g} s (--seconds)" if args.seconds
             else "until the source ended (--seconds 0)")
    print(f"recorded {s.recorded_seconds:.1f} s {asked}")
    if stopped:  # as `run` stopped by its first Ctrl-C: the file is closed and complete, the work is not
        print_summary(args.out)
        raise StoppedOnRequest(f"stopped on request after {s.recorded_seconds:.1f} s; the session file keeps "
                               f"everything recorded: {args.out}")
    code = print_summary(args.out, None if failed else args.allow_empty)  # a failure says why it is empty
    return 1 if failed else code
