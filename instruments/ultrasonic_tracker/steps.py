"""``ultrasonic_report``: the search from 12 deg off axis (Fig. 4.19) and the x-y stage (Fig. 4.22).

The search is the recorded ``direction`` stream of a simulated tracker in a shared world (a still
target, its direction in ``/truth/world``); the stage runs in process as fast as the model runs
(:func:`.experiments.stage_tracking`: 50 s and 17 s cycles would be slow in real time). Prints the
figures next to the thesis's and writes PNG figures next to the session.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import Parameter, ParameterSet, Step, figures_folder
from mirrorlab.instruments.virtual_lab.figures import Panel, Trace, plot_traces
from mirrorlab.instruments.virtual_lab.worlds import latest_truth, truth_arrays

from .experiments import stage_tracking

if TYPE_CHECKING:
    from mirrorlab.core import Session

#: §2.4, §2.6: search cycle (s, at 1.3 m), accuracy (deg), the stage's cycles (s).
THESIS = {"cycle": 0.080, "accuracy": 5.0, "line_period": 50.0, "ellipse_period": 17.0}
FOUND_DEG = 1.0                  # the search has found the target once within this


def search_panel(theta: np.ndarray, target: np.ndarray) -> Panel:
    """The platform's search path ``theta`` (n, 2) deg towards ``target`` (2,) deg.

    The path ends in a cluster of points around the target, so the target is drawn on top of
    them, as a large black star.
    """
    return Panel("search path of the platform", "theta1 (deg)", "theta2 (deg)", [
        Trace(theta[:, 0], theta[:, 1], "platform after each cycle", "o-"),
        Trace([0.0, target[0]], [0.0, target[1]], "straight line to the target", ":"),
        Trace([target[0]], [target[1]], "target (truth)", "k*", size=14.0, on_top=True)], equal=True)


class UltrasonicReport(Step):
    """``action = "ultrasonic_report"``: the recorded search and the stage experiment against §2.6."""

    name = "ultrasonic_report"
    version = "1.0.0"
    description = "print the search from an offset (Fig. 4.19) and x-y stage tracking (Fig. 4.22) next to the thesis"
    parameters = ParameterSet(
        Parameter("instrument", str, "tracker", help="the simulated ultrasonic_tracker that searched"),
        Parameter("stage", bool, True, help="run the x-y stage experiment (a few seconds)"),
        Parameter("stroke", float, 600.0, unit="mm", bounds=(1.0, 2000.0),
                  help="stage stroke and ellipse width (not in the thesis: a choice)"),
        Parameter("ellipse_height", float, 300.0, unit="mm", bounds=(0.0, 2000.0),
                  help="stage ellipse height (a choice)"),
        Parameter("seed", int, 0, bounds=(0, None), help="seed of the stage experiment's simulator"),
        Parameter("figures", str, "", output="folder", help="folder for the PNG figures (default: <session>-figures)"),
    )

    instrument_keys = ("instrument",)

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        rec = session.stream(values["instrument"], "direction")
        t, theta = rec.times, np.degrees(rec.data[:, :2])
        root = latest_truth(session)
        tr = truth_arrays(session, root)
        target = np.degrees(tr["target_angles"][-1])
        distance = float(np.linalg.norm(tr["target"][-1]))
        error = np.hypot(*(theta - target).T)
        hit = np.flatnonzero(error < FOUND_DEG)
        found = f"found within {FOUND_DEG:g} deg after {hit[0] + 1} cycles ({t[hit[0]] - t[0] + np.diff(t).mean():.2f} s)" \
            if hit.size else f"not found within {FOUND_DEG:g} deg in {t.size} cycles"
        before = slice(0, hit[0] + 1 if hit.size else t.size)
        cross = np.abs(np.cross(target / np.linalg.norm(target), theta[before]))   # off the straight start-target line
        lines = [f"ultrasonic search (Fig. 4.19): target at ({target[0]:.1f}, {target[1]:.1f}) deg, {distance / 1000:.2f} m; "
                 f"tracker {values['instrument']!r} recorded {t.size} search cycles through its driver",
                 f"{found}; final error {error[-1]:.2f} deg; the path leaves the straight line by at most "
                 f"{cross.max():.2f} deg (thesis: an almost straight path)",
                 f"search cycle: {1000 * np.median(np.diff(t)):.0f} ms at {distance / 1000:.2f} m "
                 f"(thesis: about {1000 * THESIS['cycle']:.0f} ms at 1.3 m)"]
        folder = figures_folder(session, values["figures"])
        figures = [plot_traces(folder / "ultrasonic_search.png", [search_panel(theta, target)],
                               "ultrasonic tracker: search from 12 deg off axis (Fig. 4.19)")]
        if values["stage"]:
            runs = {f"line, {values['stroke']:.0f} mm stroke, {THESIS['line_period']:.0f} s/cycle":
                    stage_tracking("stage_line", values["stroke"], 0.0, THESIS["line_period"], seed=values["seed"]),
                    f"ellipse {values['stroke']:.0f} x {values['ellipse_height']:.0f} mm, "
                    f"{THESIS['ellipse_period']:.0f} s/cycle":
                    stage_tracking("stage_ellipse", values["stroke"], values["ellipse_height"],
                                   THESIS["ellipse_period"], seed=values["seed"])}
            panels = []
            for label, (ts, tgt, plat, err) in runs.items():
                e = np.degrees(err)
                first = int(np.argmax(e < FOUND_DEG))      # from where the first search reached the target
                e = e[first:]
                lines.append(f"x-y stage (Fig. 4.22, in process) {label}: pointing error {np.sqrt(np.mean(e**2)):.2f} "
                             f"deg RMS, {e.max():.2f} deg max after the first search ({ts[first]:.1f} s) "
                             f"(thesis: accuracy about {THESIS['accuracy']:.0f} deg)")
                panels.append(Panel(f"stage {label}", "time (s)", "angle (deg)", [
                    Trace(ts, np.degrees(tgt[:, 0]), "target theta1"), Trace(ts, np.degrees(plat[:, 0]),
                                                                             "platform theta1", "--"),
                    Trace(ts, np.degrees(tgt[:, 1]), "target theta2"), Trace(ts, np.degrees(plat[:, 1]),
                                                                             "platform theta2", "--")]))
            figures.append(plot_traces(folder / "ultrasonic_stage.png", panels,
                                       "ultrasonic tracker: a target on the x-y stage (Fig. 4.22)"))
        session.write_group(f"report/ultrasonic_{root.rpartition('/')[2]}",
                            {"search_deg": theta, "search_time": t, "target_deg": target},
                            {"instrument": values["instrument"], "truth": "/" + root})
        print("\n".join(lines) + "".join(f"\nfigure: {f}" for f in figures), flush=True)


STEPS = [UltrasonicReport]
