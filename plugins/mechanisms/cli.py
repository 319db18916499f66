"""``mirrorlab mechanisms ...``: four-bar reconstruction, swept areas, the astroid check, the optimal wall.

Commands run the registered algorithms in memory (nothing is written to a session). Marker
SOURCEs are ``.npy`` files or a dataset of a session file (``--dataset /path`` or
``@algorithm/output``). Exit codes: 0 ok, 1 runtime failure (failed run), 2 usage or validation
error (missing file, bad shape, bad option value).
"""

from __future__ import annotations

import argparse
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
from mirrorlab.core import (
    Algorithm,
    Parameter,
    Problem,
    Session,
    Subcommands,
    ValidationError,
    add_parameter_options,
    collected,
    execute,
)
from mirrorlab.plugins import CommandHelp

from .algorithms import FourBarAlgorithm, OptimalWallAlgorithm, SweptArea
from .errors import MechanismError
from .fourbar import LINK_NAMES
from .steps import format_four_bar, format_walls
from .swept import segment_swept_area, strip_area
from .synthetic import THESIS_FOUR_BAR
from .walls import astroid_motion

__all__ = ["add"]


class RunFailed(MechanismError):
    """An algorithm run started from the CLI failed (its error is in the message)."""


def _load(source: str, dataset: str | None) -> np.ndarray:
    path = Path(source)
    if not path.is_file():
        raise ValidationError([Problem("SOURCE", f"no such file {source!r}")])
    if path.suffix.lower() == ".npy":
        return np.load(path)
    if not dataset:
        raise ValidationError([Problem("--dataset", f"{source} is not a .npy file: name the dataset of the session, "
                                                    "e.g. --dataset @detect_markers/xy")])
    with Session.open(path) as s:
        return np.asarray(s.read(s.resolve(dataset, "--dataset")))


def _run(algorithm: type[Algorithm], inputs: Mapping[str, Any], params: Mapping[str, Any]) -> dict[str, Any]:
    out = execute(algorithm, inputs, params)
    if out.status != "ok":
        raise RunFailed(f"{algorithm.name} failed: {out.error}")
    return out.outputs


def _print(args: argparse.Namespace, result: dict[str, Any], text: str) -> int:
    print(json.dumps(result, indent=2) if args.json else text)
    return 0


def cmd_four_bar(args: argparse.Namespace) -> int:
    points = _load(args.source, args.dataset)
    params = collected(args)
    out = _run(FourBarAlgorithm, {"points": points}, params)
    lengths = out["lengths"]
    figs = []
    if args.figures:
        from .figures import plot_four_bar

        figs.append(str(plot_four_bar(Path(args.figures) / "four_bar.png", out["tracks"], out["link"], out["joints"],
                                      title=f"{Path(args.source).name}: reconstructed four-bar")))
    reference = THESIS_FOUR_BAR if args.thesis else \
        dict(zip(LINK_NAMES, args.reference, strict=True)) if args.reference else None
    result: dict[str, Any] = {"lengths_mm": dict(zip(LINK_NAMES, np.round(lengths, 6).tolist(), strict=True)),
                              "rms_mm": round(float(out["rms"]), 6), "scale_mm_per_unit": float(out["scale"])}
    if reference is not None:
        result["reference_mm"] = reference
        result["errors_percent"] = {k: round(100 * (x - reference[k]) / reference[k], 6)
                                    for k, x in zip(LINK_NAMES, lengths.tolist(), strict=True)}
    result["figures"] = figs
    table = format_four_bar(reference, [(params.get("method", "least_squares"), lengths)], table_5_1=args.thesis,
                            reference="thesis mm" if args.thesis else "reference")
    text = table + f"\nRMS residual {float(out['rms']):.3f} mm" + "".join(f"\nfigure: {f}" for f in figs)
    return _print(args, result, text)


def _lengths(text: str) -> tuple[float, ...]:
    """``--reference G,I,C,O``: four positive lengths in mm (units allowed, as for any length)."""
    value, problem = REFERENCE.check(text)
    if problem is None and min(value) <= 0:
        problem = f"lengths must be > 0 mm, got {text!r}"
    if problem:
        raise argparse.ArgumentTypeError(problem)
    return value


#: ``--reference``: the lengths the reconstructed ones are compared with.
REFERENCE = Parameter("reference", float, unit="mm", shape=(4,), help="ground, input, coupler, output lengths")


def cmd_swept(args: argparse.Namespace) -> int:
    ends = _load(args.source, args.dataset)
    if ends.ndim != 3 or ends.shape[1] != 2:
        raise ValidationError([Problem("SOURCE", f"rod ends must be an array (T, 2, 2|3): [:, 0] = A, [:, 1] = B; "
                                                 f"got shape {ends.shape}")])
    out = _run(SweptArea, {"a": ends[:, 0], "b": ends[:, 1]}, collected(args))
    result = {"area": float(out["area"]), "crossings": out["crossings"].tolist()}
    text = f"swept area {float(out['area']):.6g} (square input units)"
    if len(out["crossings"]):
        text += f"; successive rods cross at steps {out['crossings'].tolist()} (the triangle split double-counts there)"
    return _print(args, result, text)


def cmd_astroid(args: argparse.Namespace) -> int:
    l = args.length
    a, b = astroid_motion(l, args.positions)
    exact = 3 * np.pi * l * l / 32
    vals = {"union": segment_swept_area(a, b), "strip": strip_area(a, b, args.positions),
            "raster_170px": segment_swept_area(a, b, "raster", pixel=l / 170),
            "raster_256": segment_swept_area(a, b, "raster")}
    result = {"analytic": exact, **{k: {"area": v, "error_percent": 100 * (v / exact - 1)} for k, v in vals.items()}}
    lines = [f"astroid, l = {l:g}, {args.positions} positions: 3 pi l^2 / 32 = {exact:.6f}"]
    lines += [f"{k:13s} {v:.6f}  {100 * (v / exact - 1):+.4f} %" for k, v in vals.items()]
    lines.append("(thesis raster device: +4 %; the rod spans 170 px there)")
    return _print(args, result, "\n".join(lines))


def cmd_optimal_wall(args: argparse.Namespace) -> int:
    params = collected(args)
    out = _run(OptimalWallAlgorithm, {}, params)
    values = OptimalWallAlgorithm.parameters.validate(params)
    run = {"method": values["method"], "objective": values["objective"],
           "grid": (values["positions"], values["strips"]), "thesis_positions": values["thesis_positions"],
           **{k: float(out[k]) for k in ("area", "area_positions", "area_thesis", "area_grid", "start_area", "seconds")},
           "iterations": int(out["iterations"]), "evaluations": int(out["evaluations"])}
    figs = []
    if args.figures:
        from .figures import plot_walls

        y = np.linspace(0, values["l"], 101)
        optimal = f"optimal wall, area {run['area']:.4f}"
        figs.append(str(plot_walls(Path(args.figures) / "optimal_wall.png",
                                   {"vertical wall": (0 * y, y), optimal: (out["w"], out["nodes"])},
                                   title="optimal wall", polylines=[optimal])))
    run["w"] = np.round(out["w"], 6).tolist()
    run["figures"] = figs
    return _print(args, run, format_walls(None, [run]) + "".join(f"\nfigure: {f}" for f in figs))


def _common(p: argparse.ArgumentParser, source: bool = True) -> None:
    if source:
        p.add_argument("source", help=".npy array, or a session file (.h5) with --dataset")
        p.add_argument("--dataset", help="dataset of the session: /path or @algorithm/output")
    p.add_argument("--json", action="store_true", help="print the result as JSON")


DESCRIPTION = ("Commands run the registered algorithms in memory (nothing is written to a session). Marker SOURCEs "
               "are .npy files or a dataset of a session file (--dataset /path or @algorithm/output).")


def add(subparsers: Subcommands) -> None:
    """Register ``mirrorlab mechanisms`` and its subcommands."""
    m = subparsers.add_parser("mechanisms", help=CommandHelp.mechanisms,
                              description=DESCRIPTION)
    sub = m.add_subparsers(dest="mechanisms_command", metavar="SUBCOMMAND", required=True)

    p = sub.add_parser("four-bar", help="planar four-bar from unlabeled markers (T, M, 2)")
    _common(p)
    p.add_argument("--figures", metavar="DIR", help="write a PNG of the reconstructed linkage into DIR")
    compare = p.add_mutually_exclusive_group()
    compare.add_argument("--reference", type=_lengths, metavar="G,I,C,O",
                         help="known ground, input, coupler, output lengths [mm]: print each link's error against "
                              "them (without it the lengths are printed alone)")
    thesis = ", ".join(f"{v:g}" for v in THESIS_FOUR_BAR.values())
    compare.add_argument("--thesis", action="store_true",
                         help=f"the markers are of the thesis's four-bar ({thesis} mm, e.g. from four_bar_markers): "
                              "compare with it and its Table 5.1")
    add_parameter_options(p, FourBarAlgorithm.parameters)
    p.set_defaults(func=cmd_four_bar)

    p = sub.add_parser("swept", help="area swept by a rod; SOURCE holds its ends (T, 2, 2|3)")
    _common(p)
    add_parameter_options(p, SweptArea.parameters)
    p.set_defaults(func=cmd_swept)

    p = sub.add_parser("astroid", help="the astroid check 3 pi l^2 / 32: union, strip, thesis raster")
    _common(p, source=False)
    p.add_argument("--length", type=float, default=3.0, help="rod length l (default 3)")
    p.add_argument("--positions", type=int, default=1000, help="rod positions (default 1000)")
    p.set_defaults(func=cmd_astroid)

    p = sub.add_parser("optimal-wall", help="the 59-variable optimal wall of §6.2.1")
    _common(p, source=False)
    p.add_argument("--figures", metavar="DIR", help="write a PNG of the wall into DIR")
    add_parameter_options(p, OptimalWallAlgorithm.parameters)
    p.set_defaults(func=cmd_optimal_wall)
