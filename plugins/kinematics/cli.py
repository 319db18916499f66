"""``mirrorlab kinematics ...``: import/export marker sets, derivatives, joint angles, rigid bodies.

Every analysis command takes a SOURCE that is either a session file (``.h5``; the marker set
``--dataset NAME`` under ``/markers``, results stored with provenance through ``Session.run``) or
a marker file (``.c3d``, ``.trc``, ``.tsv``; computed in memory, nothing stored). Markers are
named by label (``Daphnee:STER`` or just ``STER`` when unique, ``RKNE#9`` for marker 9 when
several share the label ``RKNE``); ``A+B`` means the midpoint of A and B. Exit codes: 0 ok, 1
runtime failure (unreadable file, failed run), 2 usage or validation error (unknown marker,
missing file, bad option value).
"""

from __future__ import annotations

import argparse
import contextlib
import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from mirrorlab.core import (
    Algorithm,
    EventBus,
    ParameterSet,
    Problem,
    RunContext,
    Session,
    SessionClock,
    Subcommands,
    ValidationError,
    add_overwrite_option,
    add_parameter_options,
    collected,
    execute,
    is_hdf5,
    plain,
    progress_bar,
)
from mirrorlab.plugins import CommandHelp

from .algorithms import (
    UPPER_LIMB_OUTPUTS,
    AngularMomentum,
    Derivatives,
    ISBAngles,
    RigidBodyMotionAlgorithm,
    UpperLimbAnglesAlgorithm,
)
from .errors import KinematicsError, KinematicsIOError
from .io import MarkerData, distinct_labels
from .store import (
    export_markers,
    import_markers,
    marker_names,
    marker_time,
    read_marker_file,
    read_markers,
    resolve_label,
)

THESIS_POINTS = ("P0", "P1", "P2", "P3", "P4", "P5")
ISB_POINTS = ("GH", "EL", "EM", "IJ", "PX", "C7", "T8", "US", "RS")


class RunFailed(KinematicsError):
    """An algorithm run started from the CLI failed (its error is in the message)."""


# ------------------------------------------------------------------------------------------------
# sources: a session's marker set or a marker file
# ------------------------------------------------------------------------------------------------
@dataclass
class Source:
    """Where the markers come from and where results go."""

    path: Path
    data: MarkerData
    time: np.ndarray
    session: Session | None = None
    dataset: str = ""
    runs: list[str] = field(default_factory=list)

    @property
    def group(self) -> str:
        return f"/markers/{self.dataset}"


def _is_session(path: Path) -> bool:
    return path.suffix.lower() in (".h5", ".hdf5") or is_hdf5(path)


@contextlib.contextmanager
def open_source(path: Path, dataset: str | None, fmt: str = "auto") -> Iterator[Source]:
    """Open ``path`` as a session (writable, marker set ``dataset``) or read it as a marker file."""
    if not path.exists():
        raise ValidationError([Problem("SOURCE", f"no such file {str(path)!r}; give a session (.h5) or a "
                                                 "marker file (.c3d, .trc, .tsv)")])
    if not _is_session(path):
        if dataset:
            raise ValidationError([Problem("--dataset", f"{path} is a marker file, not a session; drop --dataset")])
        data = read_marker_file(path, fmt)
        yield Source(path, data, data.time)
        return
    with Session.open(path, writable=True) as s:
        names = marker_names(s)
        if not dataset:
            if len(names) != 1:
                raise ValidationError([Problem("--dataset", f"{path} holds the marker sets {names or 'none'}; "
                                                            "choose one with --dataset NAME")])
            dataset = names[0]
        try:
            data = read_markers(s, dataset)
        except KinematicsIOError as exc:
            raise ValidationError([Problem("--dataset", str(exc))]) from None
        yield Source(path, data, marker_time(s, dataset), s, dataset.strip("/").split("/")[-1])


def marker_columns(data: MarkerData, spec: str, option: str) -> list[int]:
    """Columns of ``A`` or ``A+B+...`` (labels or unique label tails); usage error if unknown."""
    try:
        return [resolve_label(data.labels, part.strip()) for part in spec.split("+") if part.strip()]
    except KinematicsIOError as exc:
        raise ValidationError([Problem(option, str(exc))]) from None


def marker_trajectory(data: MarkerData, spec: str, option: str) -> np.ndarray:
    """(T, 3) trajectory of one marker or the mean of ``A+B`` (NaN where any part is missing)."""
    cols = marker_columns(data, spec, option)
    if not cols:
        raise ValidationError([Problem(option, "empty marker name")])
    return data.points[:, cols].mean(axis=1)


def marker_list(data: MarkerData, spec: str | None, option: str = "--markers") -> list[int]:
    """Columns of a comma-separated marker list (all markers when ``spec`` is empty)."""
    if not spec:
        return list(range(len(data.labels)))
    cols = []
    for part in spec.split(","):
        cols += marker_columns(data, part, option)
    return cols


# ------------------------------------------------------------------------------------------------
# running algorithms on a source
# ------------------------------------------------------------------------------------------------
def run_algorithm(src: Source, cls: type[Algorithm], inputs: Mapping[str, Any], params: Mapping[str, Any],
                  on_event: Any, units: Mapping[str, str] | None = None) -> dict[str, np.ndarray]:
    """Run ``cls`` through ``Session.run`` (session source) or ``execute`` (file source).

    ``units`` are the inputs' units (``Session.run``'s ``input_units``: they resolve output units
    declared as ``{values}/s``). Returns the outputs; a failed run raises :class:`RunFailed`
    (exit 1), a failed session run is stored with its error first.
    """
    if src.session is not None:
        ref = src.session.run(cls, inputs, params, input_units=units)
        src.runs.append(f"{ref.path}: {ref.status}")
        if ref.status != "ok":
            raise RunFailed(f"{cls.name} failed ({ref.path}): {ref.error}")
        return src.session.result(ref).outputs
    bus = EventBus(SessionClock())
    bus.subscribe(on_event)
    outcome = execute(cls, {k: np.asarray(v) for k, v in inputs.items()}, params,
                      RunContext(lambda done, total, msg: bus.progress(cls.name, done, total, msg)))
    if outcome.status != "ok":
        raise RunFailed(f"{cls.name} failed on {src.path}: {outcome.error}")
    return {k: np.asarray(v) for k, v in outcome.outputs.items()}


def _stats_deg(x: np.ndarray) -> dict[str, Any]:
    f = np.degrees(x[np.isfinite(x)])
    if not f.size:
        return {"frames": 0, "min_deg": None, "mean_deg": None, "max_deg": None}
    return {"frames": int(f.size), "min_deg": round(float(f.min()), 3), "mean_deg": round(float(f.mean()), 3),
            "max_deg": round(float(f.max()), 3)}


def _finish(args: argparse.Namespace, src: Source, summary: dict[str, Any], lines: list[str]) -> int:
    summary = {"source": str(src.path), "dataset": src.group if src.session else "", "runs": src.runs, **summary}
    if args.json:
        print(json.dumps(summary, indent=1, default=str))
    else:
        head = f"{src.path}" + (f":{src.group}" if src.session else "")
        print(f"{head}: {src.data.points.shape[1]} markers, {src.data.points.shape[0]} frames at {src.data.rate:g} Hz")
        for run in src.runs:
            print(run)
        for line in lines:
            print(line)
    return 0


def _figure_dir(args: argparse.Namespace) -> Path | None:
    return Path(args.figures) if getattr(args, "figures", None) else None


def _figures() -> Any:
    from . import figures  # matplotlib: imported only when figures are asked for

    return figures


# ------------------------------------------------------------------------------------------------
# commands
# ------------------------------------------------------------------------------------------------
def cmd_import(args: argparse.Namespace) -> int:
    path = Path(args.file)
    if not path.is_file():
        raise ValidationError([Problem("FILE", f"no such marker file {str(path)!r}")])
    out = Path(args.session)
    # A failed import into a new session leaves no file (the session is a draft until written).
    opener = (Session.open(out, writable=True) if out.exists() and not args.overwrite
              else Session.create(out, description=f"markers imported from {path.name}", overwrite=args.overwrite))
    with opener as s:
        group, data = import_markers(s, path, args.name, args.format)
    missing = float(np.isnan(data.points).any(-1).mean()) if data.points.size else 0.0
    info = {"file": str(path), "session": str(out), "dataset": group, "markers": len(data.labels),
            "frames": int(data.points.shape[0]), "rate_hz": data.rate, "missing_fraction": round(missing, 6),
            "labels": data.labels}
    if args.json:
        print(json.dumps(info, indent=1))
    else:
        print(f"{path} -> {out}:{group}: {len(data.labels)} markers, {data.points.shape[0]} frames at "
              f"{data.rate:g} Hz, {100 * missing:.2f} % of marker samples missing")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    out = Path(args.out)
    fmt = args.format or out.suffix.lower().lstrip(".")
    if fmt not in ("csv", "c3d"):
        raise ValidationError([Problem("--format", f"cannot export as {fmt!r}; use csv or c3d")])
    if not Path(args.session).is_file():
        raise ValidationError([Problem("SESSION", f"no such session file {args.session!r}")])
    with Session.open(args.session) as s:
        try:
            data = read_markers(s, args.dataset)
        except KinematicsIOError as exc:
            raise ValidationError([Problem("DATASET", str(exc))]) from None
    export_markers(data, out, fmt)
    print(f"{args.session}:{args.dataset} -> {out} ({fmt}): {len(data.labels)} markers, "
          f"{data.points.shape[0]} frames at {data.rate:g} Hz")
    return 0


def cmd_derivatives(args: argparse.Namespace) -> int:
    params = collected(args)
    method = params.get("method", "smoothing_spline")
    with open_source(Path(args.source), args.dataset, args.format) as src, \
            progress_bar(not args.no_progress) as on_event:
        if src.session is not None:
            src.session.events.subscribe(on_event)
        cols = marker_list(src.data, args.markers)
        names = distinct_labels(src.data.labels)
        labels = [names[c] for c in cols]
        if src.session is not None and len(cols) == len(src.data.labels):
            inputs: dict[str, Any] = {"time": f"{src.group}/time", "values": f"{src.group}/points"}
        else:
            inputs = {"time": src.time, "values": src.data.points[:, cols]}
        # marker data are in mm and s whatever the source file used (an older session's marker group
        # may lack the unit attributes, and a subset of markers is passed as an array)
        out = run_algorithm(src, Derivatives, inputs, params, on_event, units={"time": "s", "values": "mm"})
        xs, v, a = out["smoothed"], out["velocity"], out["acceleration"]
        per = {}
        # mm, s like every other length and time mirrorlab prints
        lines = [f"{'marker':24s} {'valid %':>8s} {'max |v| mm/s':>12s} {'max |a| mm/s²':>13s}"]
        speed, accel = np.linalg.norm(v, axis=-1), np.linalg.norm(a, axis=-1)
        for k, lab in enumerate(labels):
            vs, acc = speed[:, k][np.isfinite(speed[:, k])], accel[:, k][np.isfinite(accel[:, k])]
            per[lab] = {"valid_fraction": round(float(np.isfinite(speed[:, k]).mean()), 6),
                        "max_speed_mm_s": round(float(vs.max()), 3) if vs.size else None,
                        "max_acceleration_mm_s2": round(float(acc.max()), 3) if acc.size else None}
            fmt = lambda x, w: f"{x:{w}.1f}" if x is not None else f"{'-':>{w}s}"  # noqa: E731
            lines.append(f"{lab:24s} {100 * per[lab]['valid_fraction']:8.1f} {fmt(per[lab]['max_speed_mm_s'], 12)} "
                         f"{fmt(per[lab]['max_acceleration_mm_s2'], 13)}")
        figs = []
        if (d := _figure_dir(args)) is not None:
            figs.append(str(_figures().plot_derivatives(d / "derivatives.png", src.time, labels, xs, v, a,
                                                      title=f"{src.path.name}: {method}")))
        lines += [f"figure: {f}" for f in figs]
        return _finish(args, src, {"markers": per, "figures": figs}, lines)


def read_mot(path: Path, column: str) -> tuple[np.ndarray, np.ndarray]:
    """Time (first column) and ``column`` of an OpenSim ``.mot``/``.sto`` file.

    Raises
    ------
    ValidationError
        The file is unreadable, not a .mot/.sto table, lacks ``column`` or holds a row that is not
        numbers (``--reference`` is named, with the file and the line).
    """
    def bad(reason: str) -> ValidationError:
        return ValidationError([Problem("--reference", f"{path}: {reason}")])

    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise bad(f"cannot read it as text ({exc}); give an OpenSim .mot/.sto file") from None
    h = next((i for i, ln in enumerate(lines) if ln.strip().lower().startswith("endheader")), None)
    if h is None or h + 1 >= len(lines):
        raise bad("not an OpenSim .mot/.sto file (no endheader followed by column names)")
    sep = "\t" if "\t" in lines[h + 1] else ","
    cols = [c.strip() for c in lines[h + 1].split(sep)]
    if column not in cols:
        raise bad(f"no column {column!r}; columns: {cols[:12]}")
    rows = []
    for lineno, ln in enumerate(lines[h + 2:], start=h + 3):
        if not ln.strip():
            continue
        cells = ln.split(sep)
        try:
            if len(cells) < len(cols):
                raise ValueError(f"{len(cells)} fields, the header has {len(cols)}")
            rows.append([float(x) for x in cells[: len(cols)]])
        except ValueError as exc:
            raise bad(f"line {lineno} is not a row of numbers ({exc})") from None
    if not rows:
        raise bad("no data rows after the column names")
    table = np.asarray(rows)
    return table[:, 0], table[:, cols.index(column)]


def cmd_angles(args: argparse.Namespace) -> int:
    values = collected(args)
    thesis_params = {k: v for k, v in values.items() if k in UpperLimbAnglesAlgorithm.parameters}
    isb_params = {k: v for k, v in values.items() if k in ISBAngles.parameters}
    thesis_given = [k for k in THESIS_POINTS if getattr(args, k)]
    isb_given = [k for k in ISB_POINTS if getattr(args, k)]
    if not thesis_given and not isb_given:
        raise ValidationError([Problem("markers", "map the thesis points --P0 .. --P3 (and optionally --P4 --P5) "
                                                  "and/or the ISB landmarks --GH --EL --EM ... to marker labels")])
    missing = [k for k in THESIS_POINTS[:4] if k not in thesis_given]
    if thesis_given and missing:
        raise ValidationError([Problem(f"--{k}", "required with the other thesis points") for k in missing])
    with open_source(Path(args.source), args.dataset, args.format) as src, \
            progress_bar(not args.no_progress) as on_event:
        if src.session is not None:
            src.session.events.subscribe(on_event)
        angles: dict[str, np.ndarray] = {}
        if thesis_given:
            inputs = {k: marker_trajectory(src.data, getattr(args, k), f"--{k}") for k in thesis_given}
            out = run_algorithm(src, UpperLimbAnglesAlgorithm, inputs, thesis_params, on_event)
            angles.update({k: out[k] for k in UPPER_LIMB_OUTPUTS})
        if isb_given:
            inputs = {k: marker_trajectory(src.data, getattr(args, k), f"--{k}") for k in isb_given}
            out = run_algorithm(src, ISBAngles, inputs, isb_params, on_event)
            if {"IJ", "PX", "C7", "T8"} <= set(isb_given):
                for c, n in enumerate(values.get("shoulder_sequence", "YXY")):
                    angles[f"isb_shoulder_{c + 1}_{n}"] = out["shoulder"][:, c]
            if {"US", "RS"} <= set(isb_given):
                for c, n in enumerate(("flexion", "carrying", "pronation")):
                    angles[f"isb_elbow_{n}"] = out["elbow"][:, c]
        summary = {name: _stats_deg(np.asarray(a, float)) for name, a in angles.items()}
        lines = [f"{'angle':24s} {'frames':>7s} {'min °':>9s} {'mean °':>9s} {'max °':>9s}"]
        for name, st in summary.items():
            nums = [f"{st[k]:9.2f}" if st[k] is not None else f"{'-':>9s}" for k in ("min_deg", "mean_deg", "max_deg")]
            lines.append(f"{name:24s} {st['frames']:7d} " + " ".join(nums))
        result: dict[str, Any] = {"angles": summary}
        reference = None
        if args.reference:
            column, _, path = args.reference.partition("=")
            angle = args.compare
            if not path or angle not in angles:
                raise ValidationError([Problem("--reference", "give COLUMN=FILE.mot and --compare ANGLE with an "
                                                              f"angle computed here ({', '.join(angles)})")])
            t_ref, y_ref = read_mot(Path(path), column)
            frame = np.rint(t_ref * src.data.rate).astype(int) - src.data.first_frame
            inside = (frame >= 0) & (frame < src.time.size)
            d = np.degrees(np.asarray(angles[angle], float)[frame[inside]]) - y_ref[inside]
            ok = np.isfinite(d)
            rms = float(np.sqrt(np.mean(d[ok] ** 2))) if ok.any() else float("nan")
            result["comparison"] = {"angle": angle, "reference": f"{path}:{column}", "rows": int(ok.sum()),
                                    "of": int(t_ref.size), "rms_deg": round(rms, 4),
                                    "mean_deg": round(float(d[ok].mean()), 4) if ok.any() else None}
            lines.append(f"{angle} vs {Path(path).name}:{column}: RMS {rms:.2f}° over {ok.sum()} of {t_ref.size} rows")
            reference = {angle: (t_ref, y_ref)}
        figs = []
        if (d_ := _figure_dir(args)) is not None:
            drawn = {k: a for k, a in angles.items() if np.isfinite(a).any()}
            figs.append(str(_figures().plot_angles(d_ / "angles.png", src.time, drawn, reference=reference,
                                                title=f"{src.path.name}: joint angles")))
        lines += [f"figure: {f}" for f in figs]
        result["figures"] = figs
        return _finish(args, src, result, lines)


def cmd_rigid(args: argparse.Namespace) -> int:
    values = collected(args)
    rb_params = {k: v for k, v in values.items() if k in RigidBodyMotionAlgorithm.parameters}
    inertia_given = any(k in values for k in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz", "mass"))
    with open_source(Path(args.source), args.dataset, args.format) as src, \
            progress_bar(not args.no_progress) as on_event:
        if src.session is not None:
            src.session.events.subscribe(on_event)
        cols = marker_list(src.data, args.markers)
        if len(cols) < 3:
            raise ValidationError([Problem("--markers", f"a rigid body needs >= 3 markers, got {len(cols)}")])
        inputs: dict[str, Any] = {"time": src.time, "markers": src.data.points[:, cols]}
        out = run_algorithm(src, RigidBodyMotionAlgorithm, inputs, rb_params, on_event)
        omega, rms = out["omega"], out["rms"]
        wn = np.linalg.norm(omega, axis=-1)
        posed = np.isfinite(out["R"]).all(axis=(1, 2))
        names = distinct_labels(src.data.labels)
        result: dict[str, Any] = {
            "markers": [names[c] for c in cols], "frames_with_pose": int(posed.sum()),
            "rms_mm_mean": round(float(np.nanmean(rms)), 6) if posed.any() else None,
            "omega_max_rad_s": round(float(np.nanmax(wn)), 6) if np.isfinite(wn).any() else None}
        lines = [f"pose in {posed.sum()} of {posed.size} frames; rigid-fit rms mean {result['rms_mm_mean']} mm; "
                 f"max |omega| {result['omega_max_rad_s']} rad/s"]
        H = None
        if inertia_given:
            if src.session is not None:
                run_path = src.runs[-1].split(":")[0]
                am_inputs: dict[str, Any] = {"R": f"{run_path}/R", "omega": f"{run_path}/omega"}
            else:
                am_inputs = {"R": out["R"], "omega": omega}
            am_params = {k: v for k, v in values.items() if k in AngularMomentum.parameters and k not in rb_params}
            am = run_algorithm(src, AngularMomentum, am_inputs, am_params, on_event)
            H = am["H"]
            hn = am["H_norm"][np.isfinite(am["H_norm"])]
            result["H_mean_kg_m2_s"] = round(float(hn.mean()), 9) if hn.size else None
            result["H_variation"] = round(float(am["H_variation"]), 9)
            lines.append(f"|H_G| mean {result['H_mean_kg_m2_s']} kg·m²/s, (max-min)/mean {result['H_variation']:.3e}")
        figs = []
        if (d := _figure_dir(args)) is not None:
            figs.append(str(_figures().plot_rigid(d / "rigid.png", src.time, omega, rms=rms, H=H,
                                               title=f"{src.path.name}: rigid body {'+'.join(result['markers'][:4])}")))
        lines += [f"figure: {f}" for f in figs]
        result["figures"] = figs
        return _finish(args, src, result, lines)


# ------------------------------------------------------------------------------------------------
# parser
# ------------------------------------------------------------------------------------------------
def _source_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("source", help="session file (.h5) or marker file (.c3d, .trc, .tsv)")
    p.add_argument("--dataset", help="marker set under /markers of a session (default: the only one)")
    p.add_argument("--format", default="auto", choices=("auto", "c3d", "trc", "tsv"),
                   help="marker file format (default: from the suffix)")
    p.add_argument("--figures", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")


def add(subparsers: Subcommands) -> None:
    """Register ``mirrorlab kinematics`` and its subcommands."""
    k = subparsers.add_parser("kinematics", help=CommandHelp.kinematics,
                              description=plain(__doc__.split("\n\n")[1].replace("\n", " ")))
    sub = k.add_subparsers(dest="kinematics_command", metavar="SUBCOMMAND", required=True)

    p = sub.add_parser("import", help="copy a C3D/TRC/TSV marker file into a session as /markers/<name>")
    p.add_argument("file", help="marker file (.c3d, .trc, .tsv)")
    p.add_argument("--session", required=True, help="session file (created if absent, else added to)")
    add_overwrite_option(p, "--session")
    p.add_argument("--name", help="dataset name under /markers (default: the file's stem)")
    p.add_argument("--format", default="auto", choices=("auto", "c3d", "trc", "tsv"),
                   help="marker file format (default: from the suffix)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.set_defaults(func=cmd_import)

    p = sub.add_parser("export", help="write a session marker set as CSV or C3D")
    p.add_argument("session", help="session file")
    p.add_argument("dataset", help="marker set name under /markers, or a group path holding 'points'")
    p.add_argument("--format", choices=("csv", "c3d"), help="default: from the suffix of --out")
    p.add_argument("--out", required=True, help="file to write")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("derivatives", help="smoothed positions, velocities and accelerations of markers")
    _source_options(p)
    p.add_argument("--markers", help="comma-separated labels (default: all)")
    add_parameter_options(p, Derivatives.parameters)
    p.set_defaults(func=cmd_derivatives)

    p = sub.add_parser("angles", help="upper-limb angles (thesis 6.4-6.10) and ISB joint angles")
    _source_options(p)
    for name in THESIS_POINTS:
        p.add_argument(f"--{name}", metavar="LABEL[+LABEL]", help=f"marker for {name} (thesis §6.3.2)")
    for name in ISB_POINTS:
        p.add_argument(f"--{name}", metavar="LABEL[+LABEL]", help=f"ISB landmark {name}")
    merged = list(UpperLimbAnglesAlgorithm.parameters) + [q for q in ISBAngles.parameters
                                                           if q.name not in UpperLimbAnglesAlgorithm.parameters]
    add_parameter_options(p, ParameterSet(*merged))
    p.add_argument("--reference", metavar="COLUMN=FILE.mot", help="compare with an OpenSim .mot column (degrees)")
    p.add_argument("--compare", default="theta3", help="angle compared with --reference (default theta3)")
    p.set_defaults(func=cmd_angles)

    p = sub.add_parser("rigid", help="pose and angular velocity of a marker cluster; H_G when inertia is given")
    _source_options(p)
    p.add_argument("--markers", help="comma-separated labels of the rigid cluster (>= 3; default: all)")
    add_parameter_options(p, AngularMomentum.parameters)
    p.set_defaults(func=cmd_rigid)


__all__ = ["add", "RunFailed", "open_source", "run_algorithm", "marker_trajectory"]
