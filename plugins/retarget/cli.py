"""``mirrorlab retarget run SOURCE``: stream a recorded chain through the retargeting filter.

SOURCE is a BVH file (``--joints`` are BVH joint names), a marker file (.c3d, .trc, .tsv; joints
are marker labels, ``A+B`` = midpoint) or a session (.h5, marker set ``--dataset``). The output
chain is ``--lengths`` (mm) and ``--axes``. Prints a summary (``--json``), optionally writes a CSV
and PNG figures. Exit codes: 0 ok, 1 runtime failure (unreadable file), 2 usage or validation error.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
from mirrorlab.core import (
    Parameter,
    ParameterSet,
    Problem,
    Subcommands,
    ValidationError,
    add_parameter_options,
    collected,
    parameter_type,
)
from mirrorlab.plugins import CommandHelp

from .algorithms import CHAIN_PARAMETERS, chain_from, read_motion, stream_motion
from .errors import ChainDefinitionError
from .stream import CSVSink, Sink

__all__ = ["add"]


def cmd_run(args: argparse.Namespace) -> int:
    source = Path(args.source)
    if not source.is_file():
        raise ValidationError([Problem("SOURCE", f"no such file {str(source)!r}; give a .bvh, .c3d, .trc, .tsv or .h5")])
    params = ParameterSet(*CHAIN_PARAMETERS).validate(collected(args), "options")
    try:
        chain = chain_from(params)
    except ChainDefinitionError as exc:
        raise ValidationError([Problem("--lengths/--axes", str(exc))]) from None
    motion = read_motion(source, [j.strip() for j in args.joints.split(",")], args.scale, args.skip, args.dataset or "")
    sinks: list[Sink] = [CSVSink(args.csv, chain.dof)] if args.csv else []
    stats, memory = stream_motion(motion, chain, params, sinks, realtime=args.realtime, rate=args.rate)
    out = memory.arrays()
    f = out["f"][np.isfinite(out["f"])]
    summary = {"source": motion.source, "joints": motion.names, "frames": int(motion.joints.shape[0]),
               "rate_hz": args.rate or motion.rate, "mode": "realtime" if args.realtime else "deterministic",
               "output": {"lengths_mm": chain.lengths.tolist(), "axes": list(chain.axes), "dof": chain.dof},
               "method": params["method"], "f_mean_mm2": float(f.mean()) if f.size else None,
               "f_max_mm2": float(f.max()) if f.size else None, **stats.summary()}
    if args.figures:
        from .figures import plot_chains

        idx = out["index"].astype(int)
        summary["figure"] = str(plot_chains(Path(args.figures) / "chains.png", motion.joints[idx],
                                            chain.forward(out["q"], (np.eye(3), motion.joints[idx, 0])),
                                            out["time"], out["f"], title=f"{source.name}: {params['method']} retargeting"))
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(f"{motion.source}: {summary['frames']} frames at {summary['rate_hz']:g} Hz, {chain.dof}-DOF output, "
              f"{params['method']}: mean f {summary['f_mean_mm2']:.4g} mm², max {summary['f_max_mm2']:.4g} mm²")
        print(f"{summary['mode']}: {stats.published} published, {stats.dropped} dropped, {stats.missed_deadlines} "
              f"missed deadlines, latency mean {summary['latency_mean_ms']:.2f} ms, p99 {summary['latency_p99_ms']:.2f} ms; "
              f"{stats.restarts} multistarts, {stats.late_adoptions} adopted late")
        if "figure" in summary:
            print(f"figure: {summary['figure']}")
    return 0


DESCRIPTION = ("SOURCE is a BVH file (--joints are BVH joint names), a marker file (.c3d, .trc, .tsv; joints are "
               "marker labels, A+B is their midpoint) or a session (.h5, marker set --dataset). The output chain is "
               "--lengths (mm) and --axes. Prints a summary (--json), optionally writes a CSV and PNG figures.")


def add(subparsers: Subcommands) -> None:
    """Register ``mirrorlab retarget`` and its subcommand ``run``."""
    r = subparsers.add_parser("retarget", help=CommandHelp.retarget,
                              description=DESCRIPTION)
    sub = r.add_subparsers(dest="retarget_command", metavar="SUBCOMMAND", required=True)
    p = sub.add_parser("run", help="stream a BVH / marker file / session chain through the filter")
    p.add_argument("source", help="motion file (.bvh, .c3d, .trc, .tsv) or session (.h5)")
    p.add_argument("--joints", required=True, help="input joints root to tip, comma-separated")
    p.add_argument("--dataset", help="marker set under /markers when SOURCE is a session")
    p.add_argument("--scale", type=parameter_type(Parameter("scale", float, unit="mm")), default=1.0, metavar="MM",
                   help="the length of one file unit [mm; or with a unit: '2.54 cm'] (CMU BVH: 56.444; default 1)")
    p.add_argument("--skip", type=int, default=0, help="leading frames to drop (CMU BVH: 1, the T-pose)")
    p.add_argument("--rate", type=float, default=0.0, help="filter rate in Hz (default: the file's frame rate)")
    p.add_argument("--realtime", action="store_true",
                   help="run the threaded filter at the rate, the multistart in a worker process (default: every frame once)")
    p.add_argument("--csv", help="write every published frame to this CSV file")
    p.add_argument("--figures", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    add_parameter_options(p, ParameterSet(*CHAIN_PARAMETERS))
    p.set_defaults(func=cmd_run)
