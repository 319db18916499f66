"""Recipe steps that summarise mechanism results: printed tables next to the thesis, PNG figures.

* ``four_bar_report``: every stored ``four_bar`` run against the true lengths and Table 5.1.
* ``wall_report``: the arc grid, the eq. 6.3 family and every ``optimal_wall`` run against the
  thesis's 2.552 / 2.486 / 50 h, with figures of the walls, swept region and centrodes.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import AlgorithmError, Parameter, ParameterSet, Step, figures_folder

from .fourbar import LINK_NAMES
from .swept import strip_area, swept_region
from .synthetic import TABLE_5_1
from .walls import ARC_C, ARC_H, arc_wall, astroid_motion, centrodes, eq63_motion, wall_motion

if TYPE_CHECKING:
    from mirrorlab.core import ResultData, Session

__all__ = ["STEPS", "FourBarReport", "WallReport", "format_four_bar", "format_walls"]

#: Thesis figures for the wall problem (§6.2.1): arc grid minimum, optimal wall, its cost.
THESIS_WALL = {"arc_area": 2.552, "optimal_area": 2.486, "start_area": 2.649, "hours": 50.0, "updates": 262,
               "area_calls": 32_756}


def _ok_runs(session: Session, algorithm: str) -> list[ResultData]:
    runs = [session.result(r) for r in session.results(algorithm) if r.status == "ok"]
    if not runs:
        raise AlgorithmError(f"no successful {algorithm} run in {session.path}; add a run step with "
                             f"algorithm = \"{algorithm}\" before this report")
    return runs


def format_four_bar(true: Mapping[str, float] | None, runs: list[tuple[str, np.ndarray]],
                    table_5_1: bool = True, reference: str = "true mm") -> str:
    """Table of link lengths (mm) of each method; with ``true`` lengths also each one's error (%),
    and with ``table_5_1`` the thesis's Table 5.1 beside them (only meaningful for the thesis's
    four-bar). ``reference`` heads the column of ``true``; a column is as wide as its method's name.

    Examples
    --------
    >>> print(format_four_bar({"ground": 230, "input": 100, "coupler": 220, "output": 133},
    ...                       [("least_squares", np.array([230.5, 99.9, 220.0, 133.2]))]).splitlines()[1:3])
    ['link       true mm Table 5.1     err least_squares     err', 'ground      230.00    217.10   -5.6 %        230.50   +0.2 %']
    >>> print(format_four_bar(None, [("thesis", np.array([460.0, 200.0, 440.0, 266.0]))]))
    four-bar link lengths (mm)
    link        thesis
    ground      460.00
    input       200.00
    coupler     440.00
    output      266.00
    """
    table_5_1 = table_5_1 and true is not None
    err = f" {'err':>7s}" if true is not None else ""
    widths = [max(9, len(name)) for name, _ in runs]
    head = f"{'link':8s}" + (f" {reference:>9s}" if true is not None else "") + \
        (f" {'Table 5.1':>9s} {'err':>7s}" if table_5_1 else "") + \
        "".join(f" {name:>{w}s}{err}" for (name, _), w in zip(runs, widths, strict=True))
    title = ("four-bar link lengths (mm)" if true is None else
             "four-bar link lengths (mm) and errors, next to the thesis's Table 5.1" if table_5_1 else
             "four-bar link lengths (mm) and errors against the reference lengths")
    lines = [title, head]
    for k, link in enumerate(LINK_NAMES):
        row = f"{link:8s}"
        if true is not None:
            row += f" {true[link]:9.2f}"
        if table_5_1:
            t51, e51 = TABLE_5_1[link]
            row += f" {t51:9.2f} {e51:+6.1f} %"
        for (_, lengths), w in zip(runs, widths, strict=True):
            row += f" {lengths[k]:{w}.2f}"
            if true is not None:
                row += f" {100 * (lengths[k] - true[link]) / true[link]:+6.1f} %"
        lines.append(row)
    return "\n".join(lines)


class FourBarReport(Step):
    """``action = "four_bar_report"``: the reconstructed four-bars against the truth and Table 5.1."""

    name = "four_bar_report"
    version = "1.0.0"
    description = "print every four_bar run's link lengths and errors next to Table 5.1; PNG of the linkage"
    parameters = ParameterSet(
        Parameter("instrument", str, "", help="camera whose /truth/<instrument>/analytic/lengths holds the true "
                                              "lengths (the virtual lab writes it); else true_lengths"),
        Parameter("true_lengths", float, (230.0, 100.0, 220.0, 133.0), unit="mm", shape=(4,), bounds=(0.0, None),
                  help="true ground, input, coupler, output lengths when there is no truth in the session"),
        Parameter("figures", str, "", output="folder", help="folder for the PNG figures (default: <session>-figures)"),
    )

    instrument_keys = ("instrument",)

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        from .figures import plot_four_bar

        key = f"truth/{values['instrument']}/analytic/lengths"
        if values["instrument"]:
            if not session.exists(key):
                raise AlgorithmError(f"no {key} in {session.path}: is {values['instrument']!r} a virtual-lab four-bar "
                                     "camera? (or leave instrument empty and give true_lengths)")
            true_vals = [float(x) for x in session.read(key, 0)]
        else:
            true_vals = list(values["true_lengths"])
        true = dict(zip(LINK_NAMES, true_vals, strict=True))
        folder = figures_folder(session, values["figures"])
        runs, figures = [], []
        for r in _ok_runs(session, "four_bar"):
            method = r.attrs["parameters"].get("method", "least_squares")
            runs.append((method, r.outputs["lengths"]))
            figures.append(plot_four_bar(folder / f"four_bar_{r.ref.run_id}_{method}.png", r.outputs["tracks"],
                                         r.outputs["link"], r.outputs["joints"],
                                         title=f"four-bar ({method}): tracks and reconstructed linkage"))
        text = format_four_bar(true, runs) + (f"\n(true lengths from /{key})" if values["instrument"] else "")
        session.write_group(f"report/four_bar_{len(session.results('four_bar'))}",
                            {"lengths": np.array([x for _, x in runs]), "true": np.array(true_vals)},
                            {"methods": json.dumps([m for m, _ in runs])})
        print(text + "".join(f"\nfigure: {f}" for f in figures), flush=True)


def format_walls(arc_best: np.ndarray | None, runs: list[dict[str, Any]], eq63: tuple[float, float] | None = None) -> str:
    """Summary of the wall problem next to the thesis's numbers.

    Examples
    --------
    >>> print(format_walls(np.array([-1.0, 2.2, 2.5517]), [], (2.3, 2.4968)).splitlines()[1])
    arc-wall grid minimum: 2.5517 at c = -1.0, h = 2.2 (thesis: 2.552 near h = 2.2, c = -0.8...-1.0)
    """
    lines = ["optimal wall (l = 3), next to the thesis (§6.2.1)"]
    if arc_best is not None:
        lines.append(f"arc-wall grid minimum: {arc_best[2]:.4f} at c = {arc_best[0]:.1f}, h = {arc_best[1]:.1f} "
                     f"(thesis: {THESIS_WALL['arc_area']} near h = 2.2, c = -0.8...-1.0)")
    if eq63 is not None:
        lines.append(f"eq. 6.3 wall family minimum: {eq63[1]:.4f} at h = {eq63[0]:.2f} (spec: 2.497 at h ~ 2.3)")
    for r in runs:
        lines.append(f"{r['method']} on the {r['objective']} quadrature, {r['grid'][0]} positions x {r['grid'][1]} "
                     f"strips: {r['iterations']} iterations, {r['evaluations']} area+gradient evaluations, "
                     f"{r['seconds']:.1f} s (thesis: {THESIS_WALL['updates']} updates, {THESIS_WALL['area_calls']} "
                     f"area calls, {THESIS_WALL['hours']:.0f} h; ratio {THESIS_WALL['hours'] * 3600 / r['seconds']:.0f}x)")
        lines.append(f"  converged exact area {r['area']:.4f}; positions-only quadrature {r['area_positions']:.4f} "
                     f"(spec §6: 2.4995); thesis discretisation ({r['thesis_positions']} positions, positions only) "
                     f"{r['area_thesis']:.4f} (thesis: {THESIS_WALL['optimal_area']}); objective {r['area_grid']:.4f}; "
                     f"vertical start {r['start_area']:.4f} (thesis {THESIS_WALL['start_area']})")
    return "\n".join(lines)


class WallReport(Step):
    """``action = "wall_report"``: the constrained swept-area problem against the thesis."""

    name = "wall_report"
    version = "1.0.0"
    description = "print the arc grid, eq. 6.3 family and optimal_wall runs next to the thesis; PNG figures"
    parameters = ParameterSet(
        Parameter("figures", str, "", output="folder", help="folder for the PNG figures (default: <session>-figures)"),
        Parameter("positions", int, 2000, bounds=(10, 100_000), help="rod positions of the figures and eq. 6.3 family"),
    )

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        from .figures import plot_centrodes, plot_swept, plot_walls

        n = values["positions"]
        arcs = [session.result(r) for r in session.results("arc_wall_grid") if r.status == "ok"]
        arc_best = arcs[-1].outputs["best"] if arcs else None
        walls = _ok_runs(session, "optimal_wall")
        hs = np.round(np.arange(2.2, 2.41, 0.025), 4)
        fam = [strip_area(*eq63_motion(3.0, h, n), n) for h in hs]
        eq63 = (float(hs[int(np.argmin(fam))]), float(min(fam)))
        runs = []
        for r in walls:
            o, p = r.outputs, r.attrs["parameters"]
            runs.append({"method": p.get("method", "lbfgsb"), "objective": p.get("objective", "exact"),
                         "grid": (p.get("positions", 400), p.get("strips", 1000)),
                         "thesis_positions": p.get("thesis_positions", 361),
                         **{k: float(o[k]) for k in ("area", "area_positions", "area_thesis", "area_grid", "start_area",
                                                     "seconds")},
                         "iterations": int(o["iterations"]), "evaluations": int(o["evaluations"])})
        folder = figures_folder(session, values["figures"])
        best = walls[-1].outputs
        a, b = wall_motion(best["w"], 3.0, n, best["nodes"])
        y = np.linspace(0, 3, 301)
        optimal = f"optimal wall, {runs[-1]['area']:.4f}"
        curves = {"vertical wall (astroid)": (0 * y, y),
                  f"eq. 6.3, h = {eq63[0]:.2f}": tuple(eq63_motion(3.0, eq63[0], n)[0].T),
                  optimal: (best["w"], best["nodes"])}
        if arc_best is not None:
            curves[f"best arc c = {arc_best[0]:.1f}, h = {arc_best[1]:.1f}"] = (arc_wall(arc_best[0], arc_best[1])(y), y)
        figures = [plot_walls(folder / "walls.png", curves, title="walls guiding A (l = 3; x axis stretched)",
                              polylines=[optimal]),
                   plot_swept(folder / "optimal_wall_swept.png", a, b, swept_region(a, b),
                              title="region swept with the optimal wall", unit="l units"),
                   plot_centrodes(folder / "eq63_centrodes.png", *eq63_motion(3.0, 2.2, n),
                                  *centrodes(*eq63_motion(3.0, 2.2, n)),
                                  title="centrodes of the eq. 6.3 wall, h = 2.2 (fixed centrode y = h up to Q)",
                                  unit="l units"),
                   plot_centrodes(folder / "astroid_centrodes.png", *astroid_motion(3.0, n),
                                  *centrodes(*astroid_motion(3.0, n)),
                                  title="centrodes of the astroid motion (circles of radius l and l/2)",
                                  unit="l units")]
        session.write_group(f"report/optimal_wall_{len(walls)}", {"w": best["w"], "eq63": np.array(eq63),
                                                                  "grid_c": np.array(ARC_C), "grid_h": np.array(ARC_H)},
                            {"runs": json.dumps(runs)})
        print(format_walls(arc_best, runs, eq63) + "".join(f"\nfigure: {f}" for f in figures), flush=True)


STEPS = [FourBarReport, WallReport]
