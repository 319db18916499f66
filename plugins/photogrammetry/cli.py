"""``mirrorlab calibrate`` and ``mirrorlab reconstruct`` (see ``docs/photogrammetry.md``).

Both run the registered algorithms: with a session file through :meth:`Session.run` (result with
provenance under ``/results/<algorithm>/run-NNNN``), otherwise through
:func:`mirrorlab.core.algorithms.execute`. Exit codes follow the CLI convention: 0 ok, 1 failed
run (e.g. degenerate geometry naming frame and marker), 2 usage or malformed input (a CSV problem
names file, line and reason).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from mirrorlab.core import (
    Algorithm,
    EventBus,
    Parameter,
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
    parameter_type,
    progress_bar,
)
from mirrorlab.plugins import CommandHelp

from .camera_arrays import CAMERA_KEYS, camera_kind
from .csvio import read_columns_csv, read_marker_csv, write_points_csv
from .errors import PhotogrammetryError

__all__ = ["add"]


def _algorithms() -> dict[str, type[Algorithm]]:
    from .algorithms import CalibratePinhole, CalibratePlane, ReconstructCentral, ReconstructMirror, ReconstructParallel

    return {"calibrate_plane": CalibratePlane, "calibrate_pinhole": CalibratePinhole,
            "parallel": ReconstructParallel, "central": ReconstructCentral, "mirror": ReconstructMirror}


def add(sub: Subcommands) -> None:
    """Register ``calibrate`` and ``reconstruct`` on the ``mirrorlab`` sub-command parser."""
    algs = _algorithms()
    c = sub.add_parser(
        "calibrate", help=CommandHelp.calibrate,
        description="Calibrate a camera. Pinhole from chessboard photos: --images DIR --pattern 10x7 --square MM. "
                    "Thesis plane map from points: --points FILE.csv (columns x,y,plane_x,plane_y) "
                    "--camera-center X,Y,Z. Writes /calibration/<camera> into --session FILE (created if "
                    "missing), or prints JSON with --json.")
    src = c.add_argument_group("source (one of)")
    src.add_argument("--images", metavar="DIR|GLOB", help="chessboard photos (pinhole calibration)")
    src.add_argument("--points", type=Path, metavar="CSV", help="calibration points x,y,plane_x,plane_y (plane map)")
    c.add_argument("--pattern", help="chessboard inner corners COLSxROWS, e.g. 10x7")
    c.add_argument("--square", type=parameter_type(Parameter("square", float, unit="mm")), metavar="MM",
                   help="chessboard square side [mm; units allowed: '25 mm', '2.5 cm'] (required with --images)")
    c.add_argument("--detector", choices=("classic", "sb"), default="classic", help="corner detector")
    c.add_argument("--camera-center", metavar="X,Y,Z",
                   help="camera centre F1 [mm; or with a unit: '[0.4, 0.2, 1.4] m'] (plane map)")
    c.add_argument("--session", type=Path, help="session file to write /calibration/<camera> into (created if missing)")
    add_overwrite_option(c, "--session")
    c.add_argument("--camera", default="cam", help="camera name (default cam)")
    c.add_argument("--json", action="store_true", help="print the camera as JSON (input of reconstruct --camera-file)")
    c.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_parameter_options(c, algs["calibrate_plane"].parameters, "calibrate_plane parameters")
    add_parameter_options(c, algs["calibrate_pinhole"].parameters, "calibrate_pinhole parameters")
    c.set_defaults(func=calibrate)

    r = sub.add_parser(
        "reconstruct", help=CommandHelp.reconstruct,
        description="Reconstruct 3-D markers from 2-D marker image coordinates in a session (--input NAME=/DATASET) "
                    "or a CSV file (--markers; columns frame,marker,x,y and for the mirror method xv,yv). "
                    "Writes the result into SESSION (with provenance) and/or a points CSV (--out).")
    r.add_argument("session", type=Path, nargs="?", help="session file (created if missing when the data come from CSV)")
    add_overwrite_option(r, "SESSION")
    r.add_argument("--method", required=True, choices=("parallel", "central", "mirror"), help="reconstruction method")
    r.add_argument("--markers", type=Path, metavar="CSV", help="marker image coordinates (frame,marker,x,y[,xv,yv])")
    r.add_argument("--input", action="append", default=[], metavar="NAME=/DATASET",
                   help="an algorithm input from a dataset of SESSION (e.g. real_xy=/truth/real_xy)")
    r.add_argument("--calibration", metavar="/GROUP", help="camera from a calibration group of SESSION, e.g. /calibration/cam")
    r.add_argument("--camera-file", type=Path, metavar="JSON", help="camera from the output of mirrorlab calibrate --json")
    in_mm = "[mm; or with a unit: '[0.1, 0.2, 0.9] m', '10 cm, 20 cm, 90 cm']"
    for flag, what in (("--mirror-point", f"X,Y,Z point G on the mirror {in_mm} (mirror)"),
                       ("--normal", "X,Y,Z mirror normal toward the camera (mirror; estimated from the data if absent)"),
                       ("--lengths", f"D1,D2,... link lengths {in_mm} (parallel, central)"),
                       ("--signs", "S1,S2,... +1/-1 per link (parallel; central: 0 = undecided)"),
                       ("--principal-point", "X,Y image of the optical axis (central)"),
                       ("--start", f"X,Y,Z chain start instead of K {in_mm} (central)")):
        r.add_argument(flag, metavar="V1,V2,...|/DATASET", help=what)
    r.add_argument("--out", type=Path, metavar="CSV", help="write points (frame,marker,X,Y,Z,...) to this CSV")
    r.add_argument("--json", action="store_true", help="print a JSON summary")
    r.add_argument("--no-progress", action="store_true", help="no progress bar")
    for method in ("mirror", "parallel", "central"):
        add_parameter_options(r, algs[method].parameters, f"{method} parameters")
    r.set_defaults(func=reconstruct)


# ------------------------------------------------------------------------------------------------ helpers


def _vector(text: str, option: str, unit: str = "") -> np.ndarray:
    """``"1, 2, 3"`` as an input array in ``unit`` (``"[1, 2, 3] m"`` is converted to a ``mm`` one); a
    usage error naming ``option``."""
    value, problem = Parameter(option.lstrip("-").replace("-", "_"), float, unit=unit, shape=(None,)).check(text)
    if problem:
        raise ValidationError([Problem(option, problem)])
    return np.array(value)


def _params_for(args: argparse.Namespace, algorithm: type[Algorithm], others: list[type[Algorithm]]) -> dict[str, Any]:
    given = collected(args)
    mine = {p.name for p in algorithm.parameters}
    foreign = sorted(k for k in given if k not in mine and any(k in {p.name for p in o.parameters} for o in others))
    if foreign:
        raise ValidationError([Problem("--" + k.replace("_", "-"), f"does not apply to {algorithm.name}") for k in foreign])
    return {k: v for k, v in given.items() if k in mine}


@contextmanager
def _session(path: Path | None, create: bool, description: str, overwrite: bool) -> Iterator[Session | None]:
    """The session to write into: ``path`` opened, or created (a new one replaces it with ``overwrite``)."""
    if path is None:
        yield None
        return
    if path.exists() and not (create and overwrite):
        s = Session.open(path, writable=True)
    elif create:
        s = Session.create(path, description=description, overwrite=overwrite)
    else:
        raise ValidationError([Problem("SESSION", "no such session file; check the path", str(path))])
    with s:
        yield s


def _run(session: Session | None, algorithm: type[Algorithm], inputs: dict[str, Any], params: dict[str, Any],
         progress: bool) -> tuple[dict[str, np.ndarray], str]:
    """Run through the session (stored with provenance) or directly; raise on a failed run."""
    with progress_bar(progress) as on_event:
        if session is not None:
            session.events.subscribe(on_event)
            ref = session.run(algorithm, inputs, params).require_ok(PhotogrammetryError)
            return session.result(ref).outputs, ref.path
        bus = EventBus(SessionClock())
        bus.subscribe(on_event)
        outcome = execute(algorithm, inputs, params,
                          RunContext(lambda d, t, m: bus.progress(algorithm.name, d, t, m)))
    if outcome.status != "ok":
        raise PhotogrammetryError(f"{algorithm.name} failed: {outcome.error}")
    return {k: np.asarray(v) for k, v in outcome.outputs.items()}, ""


def _jsonable(value: Any) -> Any:
    a = np.asarray(value)
    if a.dtype.kind == "S":
        return [x.decode() for x in a.ravel()]
    return a.tolist() if a.ndim else a.item()


# ------------------------------------------------------------------------------------------------ calibrate


def _calibrate_problems(args: argparse.Namespace) -> list[Problem]:
    """Every missing or unusable option of ``calibrate``, so that one run names them all."""
    from .calibration_io import parse_pattern
    from .errors import InvalidArgument

    problems = []
    if bool(args.images) == bool(args.points):
        problems.append(Problem("calibrate", "give exactly one source: --images DIR (chessboard photos) or "
                                             "--points FILE.csv (calibration points)"))
    if args.session is None and not args.json:
        problems.append(Problem("calibrate", "say where the camera goes: --session FILE and/or --json"))
    if args.images and not args.points:
        if not any(c in args.images for c in "*?[") and not Path(args.images).exists():
            problems.append(Problem("--images", f"no such folder {args.images!r}; give a folder of chessboard "
                                                "photos or a glob such as 'cal/*.png'"))
        if not args.pattern:
            problems.append(Problem("--pattern", "required with --images: chessboard inner corners, e.g. 10x7"))
        else:
            try:
                parse_pattern(args.pattern)
            except InvalidArgument as exc:
                problems.append(Problem("--pattern", str(exc)))
        if args.square is None:
            problems.append(Problem("--square", "required with --images: the chessboard square side in mm, "
                                                "e.g. --square 25 (it sets the scale of the calibration)"))
        elif args.square <= 0:
            problems.append(Problem("--square", f"must be > 0 mm, got {args.square}"))
    if args.points and not args.images and not args.camera_center:
        problems.append(Problem("--camera-center", "required with --points: camera centre X,Y,Z in mm"))
    return problems


def calibrate(args: argparse.Namespace) -> int:
    algs = _algorithms()
    if problems := _calibrate_problems(args):
        raise ValidationError(problems)
    extra: dict[str, Any] = {}
    attrs: dict[str, Any] = {}
    if args.images:
        from .calibration_io import chessboard_inputs

        algorithm = algs["calibrate_pinhole"]
        params = _params_for(args, algorithm, [algs["calibrate_plane"]])
        with progress_bar(not args.no_progress) as on_event:
            bus = EventBus(SessionClock())
            bus.subscribe(on_event)
            bus.progress("detect", 0, None, "detecting chessboard corners")
            inputs, found = chessboard_inputs(args.images, args.pattern, args.square, args.detector)
            bus.progress("detect", 1, 1, "done")
        extra = {"image_points": inputs["image_points"], "object_points": inputs["object_points"]}
        attrs = {"images": str(args.images), "pattern": args.pattern, "square_mm": args.square, **found}
    else:
        algorithm = algs["calibrate_plane"]
        center = _vector(args.camera_center, "--camera-center", "mm")
        if center.shape != (3,):
            raise ValidationError([Problem("--camera-center", f"needs 3 numbers X,Y,Z, got {center.size}")])
        params = _params_for(args, algorithm, [algs["calibrate_pinhole"]])
        cols = read_columns_csv(args.points, ("x", "y", "plane_x", "plane_y"))
        inputs = {"image_xy": np.c_[cols["x"], cols["y"]], "plane_xy": np.c_[cols["plane_x"], cols["plane_y"]],
                  "camera_center": center}
        attrs = {"points_csv": str(args.points)}
    with _session(args.session, True, "mirrorlab calibrate", args.overwrite) as s:
        if s is not None:
            from .calibration_io import require_new_camera, store_calibration

            require_new_camera(s, args.camera)
            ref = s.run(algorithm, inputs, params)
            store_calibration(s, args.camera, ref, extra, attrs)
            outputs, where = s.result(ref).outputs, f"/calibration/{args.camera}"
        else:
            outputs, where = _run(None, algorithm, inputs, params, not args.no_progress)
    model = camera_kind(outputs)
    if args.json:
        doc = {"camera": args.camera, "model": model, "algorithm": algorithm.name, "session": str(args.session or ""),
               "group": where if args.session else "", **{k: _jsonable(v) for k, v in outputs.items()},
               **{k: v for k, v in attrs.items() if k in ("found", "missing")}}
        print(json.dumps(doc, indent=1))
    else:
        unit = "px" if model == "pinhole" else "mm"
        line = f"{where}: {model} camera, RMS {float(outputs['rms']):.4g} {unit}"
        if model == "pinhole":
            K = outputs["camera_matrix"]
            line += f", fx {K[0, 0]:.2f}, fy {K[1, 1]:.2f}, cx {K[0, 2]:.2f}, cy {K[1, 2]:.2f} px, " \
                    f"{len(attrs.get('found', []))} views ({len(attrs.get('missing', []))} without board)"
        print(line)
    return 0


# ------------------------------------------------------------------------------------------------ reconstruct

#: Vector options of ``reconstruct`` (each named as the input it provides) and their units.
_VECTOR_UNITS = {"mirror_point": "mm", "normal": "", "lengths": "mm", "signs": "", "principal_point": "", "start": "mm"}


def _option_for(name: str) -> str:
    """The command-line option(s) that provide the algorithm input ``name``."""
    if name in _VECTOR_UNITS:
        return f"--{name.replace('_', '-')} V1,V2,...|/DATASET"
    if name in CAMERA_KEYS:
        return "--calibration /GROUP or --camera-file FILE.json"
    return f"--input {name}=/DATASET (or --markers FILE.csv)"


def _describe(algorithm: type[Algorithm], name: str) -> str:
    port = next(p for p in algorithm.inputs if p.name == name)
    return f"{port.description} [{port.unit}]" if port.unit else port.description


def _camera_inputs(args: argparse.Namespace, session: Session | None, algorithm: type[Algorithm]) -> dict[str, Any]:
    if args.calibration and args.camera_file:
        raise ValidationError([Problem("--calibration", "give --calibration or --camera-file, not both")])
    if args.calibration:
        if session is None:
            raise ValidationError([Problem("--calibration", "a calibration group needs SESSION; or use --camera-file")])
        from .calibration_io import calibration_inputs

        return dict(calibration_inputs(session, args.calibration, algorithm))
    if args.camera_file:
        try:
            doc = json.loads(Path(args.camera_file).read_text())
        except (OSError, ValueError) as exc:
            raise ValidationError([Problem("--camera-file", f"not a readable JSON camera ({exc})",
                                           str(args.camera_file))]) from None
        return {k: np.asarray(v, float) for k, v in doc.items() if k in CAMERA_KEYS}
    return {}


def reconstruct(args: argparse.Namespace) -> int:
    algs = _algorithms()
    algorithm = algs[args.method]
    params = _params_for(args, algorithm, [algs[m] for m in ("parallel", "central", "mirror")])
    if args.session is None and args.out is None:
        raise ValidationError([Problem("reconstruct", "say where the result goes: SESSION and/or --out FILE.csv")])
    if not args.markers and not args.input:
        raise ValidationError([Problem("reconstruct", "give the 2-D data: --markers FILE.csv or --input NAME=/DATASET")])
    csv_inputs: dict[str, Any] = {}
    if args.markers:
        names = ("x", "y", "xv", "yv") if args.method == "mirror" else ("x", "y")
        table = read_marker_csv(args.markers, names)
        if args.method == "mirror":
            csv_inputs = {"real_xy": table.xy("x", "y"), "virtual_xy": table.xy("xv", "yv")}
        else:
            csv_inputs = {"image_xy": table.xy("x", "y")}
    with _session(args.session, bool(args.markers), f"mirrorlab reconstruct --method {args.method}",
                  args.overwrite) as s:
        inputs: dict[str, Any] = {**_camera_inputs(args, s, algorithm), **csv_inputs}
        for item in args.input:
            name, sep, path = item.partition("=")
            if not sep or not path.startswith("/"):
                raise ValidationError([Problem("--input", f"{item!r} is not NAME=/DATASET")])
            if s is None:
                raise ValidationError([Problem("--input", "dataset inputs need SESSION")])
            inputs[name] = path
        for name, unit in _VECTOR_UNITS.items():
            text = getattr(args, name)
            if text is None:
                continue
            if text.startswith("/"):
                if s is None:
                    raise ValidationError([Problem(f"--{name.replace('_', '-')}", "a dataset path needs SESSION")])
                inputs[name] = text
            else:
                inputs[name] = _vector(text, f"--{name.replace('_', '-')}", unit)
        declared = {p.name for p in algorithm.inputs}
        unknown = sorted(set(inputs) - declared)
        if unknown:
            raise ValidationError([Problem(f"inputs.{k}", f"{algorithm.name} takes no input {k!r}; it takes: "
                                           f"{', '.join(sorted(declared))}") for k in unknown])
        missing = [p.name for p in algorithm.inputs if not p.optional and p.name not in inputs]
        if missing:
            raise ValidationError([Problem(name, f"--method {args.method} needs {_describe(algorithm, name)}; "
                                                 f"pass {_option_for(name)}") for name in missing])
        outputs, where = _run(s, algorithm, inputs, params, not args.no_progress)
    points = outputs["points"]
    if args.out is not None:
        extra = {"mirror": ("gap", "angle"), "central": ("signs", "tangent_ray"),
                 "parallel": ("segment_in_image_plane",)}[args.method]
        write_points_csv(args.out, points, {k: outputs[k] for k in extra})
    ok = np.isfinite(points).all(-1)
    summary = {"method": args.method, "algorithm": algorithm.name, "result": where, "out": str(args.out or ""),
               "frames": int(points.shape[0]), "markers": int(points.shape[1]), "reconstructed": int(ok.sum())}
    if "gap" in outputs and ok.any():
        summary["median_gap_mm"] = float(np.nanmedian(outputs["gap"]))
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        dest = " and ".join(x for x in (where, str(args.out or "")) if x)
        gap = f", median gap {summary['median_gap_mm']:.3g} mm" if "median_gap_mm" in summary else ""
        print(f"{dest}: {summary['reconstructed']} of {summary['frames']} x {summary['markers']} markers "
              f"reconstructed ({args.method}){gap}")
    return 0

