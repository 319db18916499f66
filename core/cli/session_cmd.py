"""``mirrorlab session``: create, inspect, check, close and export session files."""

from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import h5py
import numpy as np

from ..errors import Problem, SessionError, ValidationError
from ..session import Session
from ..store import files
from .options import existing_path


def add(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("session", help="create, inspect, check, close and export session files")
    ssub = p.add_subparsers(dest="session_command", metavar="SUBCOMMAND", required=True)
    n = ssub.add_parser("new", help="create an empty session file")
    n.add_argument("file", type=Path, help="session file to create (.h5)")
    n.add_argument("--operator", default="", help="who records (stored in the file)")
    n.add_argument("--description", default="", help="what the session is (stored in the file)")
    n.set_defaults(func=new)
    for name, func, helptext in (("info", info, "attributes, instruments, streams, results"),
                                 ("tree", tree, "every group and dataset"),
                                 ("check", check, "consistency; exit 1 if the session is incomplete")):
        c = ssub.add_parser(name, help=helptext)
        c.add_argument("file", type=existing_path, help="session file (.h5)")
        c.add_argument("--json", action="store_true", help="machine-readable output")
        c.set_defaults(func=func)
    c = ssub.add_parser("close", help="mark a session closed (or --aborted), repairing a crashed file")
    c.add_argument("file", type=existing_path, help="session file (.h5)")
    c.add_argument("--aborted", action="store_true", help="mark it aborted (a recording that did not finish)")
    c.set_defaults(func=close)
    e = ssub.add_parser("export", help="export a stream or result dataset to CSV or .npy")
    e.add_argument("file", type=existing_path, help="session file (.h5)")
    e.add_argument("dataset", help="instrument/stream (e.g. cam/frame_index) or a dataset path")
    e.add_argument("--out", type=Path, help="output file (default: stdout for CSV)")
    e.add_argument("--format", choices=("csv", "npy"), default="csv", help="csv (default) or npy (needs --out)")
    e.set_defaults(func=export)


def new(args: argparse.Namespace) -> int:
    with Session.create(args.file, operator=args.operator, description=args.description):
        pass
    print(f"created {args.file}")
    return 0


def info(args: argparse.Namespace) -> int:
    with Session.open(args.file) as s:
        data = s.describe()
    if args.json:
        print(json.dumps(data, indent=2, default=str))
        return 0
    a = data["attributes"]
    print(f"{data['path']}: session {a.get('session_id')} [{a.get('status')}]"
          + ("  (left open by a crash: read through SWMR)" if data["crashed"] else ""))
    for key in ("created_utc", "operator", "description", "mirrorlab_version", "mirrorlab_schema"):
        print(f"  {key}: {a.get(key)}")
    for label, inst in data["instruments"].items():
        ident = inst["identity"]
        print(f"  instrument {label}: {inst['plugin']} {inst['version']}"
              + (f" — {ident.get('kind')} {ident.get('model')} fw {ident.get('firmware')}" if ident else ""))
        for name, st in inst["streams"].items():
            print(f"    {name}: {st['samples']} x {st['shape']} {st['dtype']} [{st['unit']}]")
    for r in data["results"]:
        print(f"  result {r['path']}: {r['status']} {r['error']}")
    print(f"  log: {data['log_events']} events")
    return 0


def tree(args: argparse.Namespace) -> int:
    f, _ = files.open_readonly(args.file)
    items = []
    with f:
        def visit(name: str, obj: h5py.HLObject) -> None:
            entry = {"path": "/" + name, "type": "group" if isinstance(obj, h5py.Group) else "dataset",
                     "attrs": sorted(obj.attrs)}
            if isinstance(obj, h5py.Dataset):
                entry.update(shape=list(obj.shape), dtype=str(obj.dtype))
            items.append(entry)
        f.visititems(visit)
    if args.json:
        print(json.dumps(items, indent=2))
        return 0
    for e in items:
        depth = e["path"].count("/") - 1
        detail = f"  {e['shape']} {e['dtype']}" if e["type"] == "dataset" else "/"
        print("  " * depth + e["path"].rsplit("/", 1)[-1] + detail)
    return 0


def check(args: argparse.Namespace) -> int:
    report = files.check(args.file)
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
    else:
        state = "complete" if report.complete else "INCOMPLETE"
        print(f"{report.path}: {state} (status {report.status!r}, schema {report.schema})")
        for p in report.problems:
            print(f"  - {p}")
        for name, st in report.streams.items():
            print(f"  {name}: {st['samples']} samples")
    return 0 if report.complete else 1


def close(args: argparse.Namespace) -> int:
    status = "aborted" if args.aborted else "closed"
    report = files.check(args.file)
    if report.status in ("closed", "aborted") and not report.open_for_write:
        print(f"{args.file} is already {report.status}")
        return 0 if report.status == status else 1
    files.mark_status(args.file, status)
    repaired = " (repaired the crash-flagged file first)" if report.open_for_write else ""
    print(f"{args.file}: status set to {status}{repaired}")
    return 0


def export(args: argparse.Namespace) -> int:
    with Session.open(args.file) as s:
        if args.dataset.startswith("/"):
            if args.dataset.strip("/") not in s.file or not isinstance(s.file[args.dataset], h5py.Dataset):
                raise SessionError(f"no dataset {args.dataset} in {args.file}; `mirrorlab session tree` lists them")
            times, data = None, s.file[args.dataset][()]
        else:
            inst, _, stream = args.dataset.partition("/")
            times, data = s.stream(inst, stream)
    if args.format == "npy":
        if not args.out:
            raise ValidationError([Problem("--format npy", "needs --out FILE (binary data does not go to the terminal)")])
        np.save(args.out, data)
        print(f"wrote {args.out}")
        return 0
    flat = data.reshape(len(data), -1) if data.ndim > 1 else data.reshape(-1, 1)
    if flat.shape[1] > 4096:
        raise SessionError(f"{args.dataset} has {flat.shape[1]} values per sample; use --format npy")
    out = open(args.out, "w", newline="") if args.out else sys.stdout
    try:
        w = csv.writer(out)
        header = ([] if times is None else ["time_s"]) + [f"v{i}" for i in range(flat.shape[1])]
        w.writerow(header)
        for i, row in enumerate(flat):
            w.writerow(([] if times is None else [repr(float(times[i]))]) + [repr(v.item()) for v in row])
    finally:
        if args.out:
            out.close()
    return 0
