"""``mirrorlab session``: create, inspect, check, close and export session files."""

from __future__ import annotations

import argparse
import csv
import itertools
import json
import sys
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import Problem, SessionError, ValidationError
from ..params import control_problem
from ..session import Session
from ..store import files
from ..store.reader import file_tree
from .options import existing_path
from .outputs import escaped, group_contents, plural, printable


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
        if func is check:
            c.add_argument("--data", action="store_true",
                           help="also read every recorded sample and verify its checksum (slow for long recordings)")
        c.set_defaults(func=func)
    c = ssub.add_parser("close", help="mark a session closed (or --aborted), repairing a crashed file")
    c.add_argument("file", type=existing_path, help="session file (.h5)")
    c.add_argument("--aborted", action="store_true", help="mark it aborted (a recording that did not finish)")
    c.set_defaults(func=close)
    e = ssub.add_parser("export", help="export a stream or result dataset to CSV or .npy")
    e.add_argument("file", type=existing_path, help="session file (.h5)")
    e.add_argument("dataset", help="instrument/stream (e.g. cam/frame_index) or a dataset path")
    e.add_argument("--out", type=Path, help="output file: FILE.npy with --format npy, any other name for CSV "
                                            "(default: CSV on stdout)")
    e.add_argument("--format", choices=("csv", "npy"), default="csv", help="csv (default) or npy (needs --out FILE.npy)")
    e.set_defaults(func=export)


def new(args: argparse.Namespace) -> int:
    if problems := [Problem(f"--{key}", reason) for key in ("operator", "description")
                    if (reason := control_problem(getattr(args, key)))]:
        raise ValidationError(problems)
    with Session.create(args.file, operator=args.operator, description=args.description):
        pass
    print(f"created {args.file}")
    return 0


def info(args: argparse.Namespace) -> int:
    with files.reading(args.file), Session.open(args.file) as s:
        data = s.describe()
    data["not_utf8"] = _replaced(data)
    if args.json:
        print(json.dumps(data, indent=2, default=str))
        return 0
    data = escaped(data)  # a file from another lab may hold terminal escapes (JSON escapes them itself)
    a = data["attributes"]
    if data["writer"]:
        state = f"  (being recorded right now by {data['writer']}: read through SWMR)"
    else:
        state = "  (left open by a crash: read through SWMR)" if data["crashed"] else ""
    print(f"{data['path']}: session {a.get('session_id')} [{a.get('status')}]{state}")
    for key in ("created_utc", "clock_origin_utc", "operator", "description", "mirrorlab_version",
                "mirrorlab_schema"):
        if key in a:  # a schema 1 file has no clock_origin_utc
            print(f"  {key}: {a[key]}")
    for label, inst in data["instruments"].items():
        ident = inst["identity"]
        print(f"  instrument {label}: {inst['plugin']} {inst['version']}"
              + (f" — {ident.get('kind')} {ident.get('model')} fw {ident.get('firmware')}" if ident else ""))
        _print_streams(inst["streams"])
    for label, c in data.get("controllers", {}).items():
        bound = ", ".join([f"{role} <- {ref}" for role, ref in c["inputs"].items()]
                          + [f"{role} -> {ref}" for role, ref in c["instruments"].items()])
        print(f"  controller {label}: {c['plugin']} {c['version']} ({bound})")
        _print_streams(c["streams"])
    for path, g in data["groups"].items():
        print(f"  {path}: {group_contents(g)}")
    for r in data["results"]:
        label = f" as {r['label']!r}" if r["label"] else ""
        print(f"  result {r['path']}{label}: {r['status']}" + (f" — {r['error']}" if r["error"] else ""))
        for name, out in r["outputs"].items():
            shape = "×".join(map(str, out["shape"])) or "scalar"
            print(f"    {name}: {shape} {out['dtype']}" + (f" [{out['unit']}]" if out["unit"] else ""))
    print(f"  log: {data['log_events']} events")
    if data["recovered"]:
        print(f"  note: {data['recovered']}")
    if data["not_utf8"]:
        print(f"  note: text in the file that is not valid UTF-8, shown with \N{REPLACEMENT CHARACTER} for the bytes that "
              f"could not be decoded: {', '.join(data['not_utf8'])}")
    return 0


def _print_streams(streams: dict[str, dict[str, Any]]) -> None:
    for name, st in streams.items():
        sample = "×".join(map(str, st["shape"])) + " " if st["shape"] else ""
        unit = f" [{st['unit']}]" if st["unit"] else ""
        n = st["samples"]
        print(f"    {name}: {n} sample{'' if n == 1 else 's'} of {sample}{st['dtype']}{unit}")


def _replaced(data: object, where: str = "") -> list[str]:
    """Where (dotted keys) the nested summary holds text with U+FFFD: bytes that were not UTF-8."""
    if isinstance(data, dict):
        return [w for k, v in data.items() for w in _replaced(v, f"{where}.{k}" if where else str(k))]
    if isinstance(data, list):
        return [w for i, v in enumerate(data) for w in _replaced(v, f"{where}[{i}]")]
    return [where] if isinstance(data, str) and "\N{REPLACEMENT CHARACTER}" in data else []


def tree(args: argparse.Namespace) -> int:
    items = []
    for node in file_tree(args.file):  # any HDF5 file, not only a session's
        entry: dict[str, Any] = {"path": node.path, "type": "dataset" if node.is_dataset else "group",
                                 "attrs": list(node.attrs)}
        if node.is_dataset:
            entry.update(shape=list(node.shape), dtype=str(node.dtype))
        items.append(entry)
    if args.json:
        print(json.dumps(items, indent=2))
        return 0
    for e in items:
        depth = e["path"].count("/") - 1
        detail = f"  {e['shape']} {e['dtype']}" if e["type"] == "dataset" else "/"
        print("  " * depth + printable(e["path"].rsplit("/", 1)[-1]) + detail)
    return 0


def check(args: argparse.Namespace) -> int:
    report = files.check(args.file, data=args.data)
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
    else:
        state = "complete" if report.complete else "INCOMPLETE"
        print(f"{report.path}: {state} (status {report.status!r}, schema {report.schema})")
        for note in report.notes:
            print(f"  note: {note}")
        for p in report.problems:
            print(f"  - {p}")
        for name, st in report.streams.items():
            print(f"  {name}: {st['samples']} samples")
        if report.checksums is False:
            print("  (written without checksums: the samples were read but cannot be verified)")
    return 0 if report.complete else 1


def close(args: argparse.Namespace) -> int:
    status = "aborted" if args.aborted else "closed"
    report = files.check(args.file)
    if report.status in ("closed", "aborted") and not report.open_for_write:
        print(f"{args.file} is already {report.status}")
        return 0 if report.status == status else 1
    if report.schema is None or (report.status != "open" and not report.open_for_write):
        raise SessionError(f"{args.file} is not a mirrorlab session that can be closed ({'; '.join(report.problems)}); "
                           "it is left as it is")
    notes: list[str] = []
    with files.reading(args.file):
        files.mark_status(args.file, status, notes)
    repaired = " (repaired the crash-flagged file first)" if report.open_for_write else ""
    print(f"{args.file}: status set to {status}{repaired}")
    for note in [*report.notes, *notes]:
        print(f"  note: {note}")
    return 0


def export(args: argparse.Namespace) -> int:
    if args.format == "npy" and not args.out:
        raise ValidationError([Problem("--format npy", "needs --out FILE.npy (binary data does not go to the terminal)")])
    if args.out and (args.out.suffix.lower() == ".npy") != (args.format == "npy"):
        # numpy would append .npy to any other name; CSV text in a .npy file would fool numpy readers
        fix = f"name the file {args.out.stem}.npy" if args.format == "npy" else "add --format npy, or name a .csv file"
        raise ValidationError([Problem("--out", f"{args.out} does not fit --format {args.format}: {fix}")])
    with files.reading(args.file), Session.open(args.file) as s:
        if args.dataset.startswith("/"):
            if not s.exists(args.dataset) or not s.node(args.dataset).is_dataset:
                raise ValidationError([Problem("DATASET", f"no dataset {args.dataset} in {args.file}; "
                                                          "`mirrorlab session tree` lists them")])
            times, data, columns = None, np.atleast_1d(s.read(args.dataset)), column_names(s, args.dataset)
        else:
            source, _, stream = args.dataset.partition("/")
            key = next((k for k in (f"/instruments/{source}/{stream}", f"/controllers/{source}/{stream}")
                        if stream and s.exists(k)), None)
            if key is None:
                raise ValidationError([Problem("DATASET", f"no stream {args.dataset} in {args.file}; "
                                                          "`mirrorlab session info` lists the streams")])
            times, data = s.stream(source, stream)
            columns = [f"time_{s.attributes(key).get('time_unit', 's')}", *column_names(s, f"{key}/data")]
    if args.format == "npy":
        np.save(args.out, data)
        print(f"wrote {args.out}: {plural(len(data), 'sample')} of {'x'.join(map(str, data.shape[1:])) or 'scalar'} "
              f"{data.dtype}")
        return 0
    flat = data.reshape(len(data), int(np.prod(data.shape[1:])))  # also for 0 samples
    if flat.shape[1] > 4096:
        raise ValidationError([Problem("--format", f"{args.dataset} has {flat.shape[1]} values per sample, too many "
                                                   "columns for CSV; use --format npy --out FILE.npy")])
    out = open(args.out, "w", newline="") if args.out else sys.stdout
    try:
        w = csv.writer(out)
        w.writerow(columns)
        for i, row in enumerate(flat):
            w.writerow(([] if times is None else [repr(float(times[i]))]) + [repr(v.item()) for v in row])
    finally:
        if args.out:
            out.close()
    if args.out:  # on stdout the CSV is all there is
        print(f"wrote {args.out}: {plural(len(flat), 'row')} of {plural(len(columns), 'column')}")
    return 0


def column_names(session: Session, path: str) -> list[str]:
    """CSV column names of a dataset's values, one per value of a sample (axis 0 is the sample).

    The name is the stream's (for ``<stream>/data``) or the dataset's, with the sample index
    (``xy_3_1``) or, for the first sample axis, the names a ``labels`` attribute of the dataset or
    its group declares (``points_S_A_0``); then the unit (``unit``/``units`` of the dataset, or
    the stream's ``unit``), as in the kinematics CSV files: ``temperature_K``.
    """
    group, _, own = path.rstrip("/").rpartition("/")
    stream = own == "data" and "time" in session.members(group)
    name = group.rsplit("/", 1)[-1] if stream else own
    attrs, group_attrs = session.attributes(path), session.attributes(group or "/")
    unit = _text(attrs, "unit") or _text(attrs, "units") or (_text(group_attrs, "unit") if stream else "")
    suffix = f"_{unit}" if unit else ""
    shape = session.node(path).shape[1:]
    if not shape:
        return [name + suffix]
    labels = _labels(attrs) or _labels(group_attrs)
    axes: list[list[str]] = [[str(i) for i in range(n)] for n in shape]
    if labels and len(labels) == shape[0]:
        axes[0] = labels
    return ["_".join((name, *index)) + suffix for index in itertools.product(*axes)]


def _text(attrs: dict[str, Any], name: str) -> str:
    """Attribute ``name`` as text (``""`` if absent)."""
    return str(attrs.get(name, ""))


def _labels(attrs: dict[str, Any]) -> list[str]:
    """The ``labels`` attribute (a JSON list, as ``Session.write_group`` stores it), or ``[]``."""
    labels = attrs.get("labels", [])
    if isinstance(labels, str):
        try:
            labels = json.loads(labels)
        except ValueError:  # not JSON text: one name
            pass
    return [str(x.decode() if isinstance(x, bytes) else x) for x in np.atleast_1d(labels)]
