"""``active_mirror_report``: the walk of Fig. 4.40 and the tracking-rate limit, next to the thesis.

Reads the recorded gimbal (and an optional fixed detector) and the shared world's truth
(``/truth/world``), runs the tracking-limit experiment in process (:mod:`.experiments`, as fast as
the model runs), prints the figures beside the thesis's and writes PNG figures next to the session.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import AlgorithmError, Parameter, ParameterSet, Step, figures_folder
from mirrorlab.instruments.virtual_lab.figures import Panel, Trace, plot_traces
from mirrorlab.instruments.virtual_lab.world import image_in_mirror, mirror_normal
from mirrorlab.instruments.virtual_lab.worlds import latest_truth, truth_arrays

from .experiments import fixed_mirror_width, tracking_limit

if TYPE_CHECKING:
    from mirrorlab.core import Session

#: The thesis's figures (§4.3): the tracking limit, deg/s; the fixed mirror a walk would need, m.
THESIS = {"limit": 15.0, "fixed_mirror_m": 3.0}
#: Motor and backlash variants of the limit experiment: label -> (torque factor, SIM:FAULT arguments).
VARIANTS = {"default calibrated motor": (1.0, ()), "stronger motor (TORQUE H 2)": (2.0, ("TORQUE H 2",)),
            "backlash removed (BACKLASH H 0)": (1.0, ("BACKLASH H 0",)),
            "stronger motor, no backlash": (2.0, ("TORQUE H 2", "BACKLASH H 0"))}
RISE_DEG_S = 0.5                 # a variant "raises" the limit by more than twice the bisection tolerance


class ActiveMirrorReport(Step):
    """``action = "active_mirror_report"``: the walk of Fig. 4.40 and the tracking limit."""

    name = "active_mirror_report"
    version = "1.0.0"
    description = ("print the walk's in-mirror frames, the fixed mirror it would need and the tracking limit "
                   "(default, stronger motor, no backlash) next to the thesis; PNG figures")
    parameters = ParameterSet(
        Parameter("instrument", str, "mirror", help="the simulated mirror_gimbal that tracked the walk"),
        Parameter("fixed", str, "", help="a fixed line_tracker beside the mirror (optional)"),
        Parameter("limits", bool, True, help="run the tracking-limit experiment (about 1 s per variant)"),
        Parameter("seed", int, 0, bounds=(0, None), help="seed of the limit experiment's simulator"),
        Parameter("figures", str, "", output="folder", help="folder for the PNG figures (default: <session>-figures)"),
    )

    instrument_keys = ("instrument", "fixed")

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        root = latest_truth(session)
        tr = truth_arrays(session, root)
        settings = session.json_attribute(root, "settings", {})
        camera = np.asarray(session.json_attribute(root, "camera"), float)
        centre = np.asarray(session.json_attribute(root, "mirror_centre"), float)
        attrs = session.attributes(root)
        size, radius = float(attrs["mirror_size"]), float(attrs["target_radius"])
        t = tr["time"]
        start = float(settings["start"])
        end = start + float(settings["width"]) / float(settings["speed"])
        walk = (t >= start) & (t <= end)
        if not walk.any():
            raise AlgorithmError(f"the recording ({t[0]:.2f}-{t[-1]:.2f} s) holds none of the walk "
                                 f"({start:.2f}-{end:.2f} s session time); record longer")
        n0 = mirror_normal(0.0, 0.0, camera - centre)
        fixed_in = np.array([image_in_mirror(camera, p, centre, n0, size, radius) for p in tr["target"]])
        rate = np.degrees(np.abs(np.gradient(tr["target_angles"][:, 0], t)))
        need = fixed_mirror_width(camera, centre, tr["target"][walk], radius) / 1000.0
        gimbal = session.stream(values["instrument"], "h")
        half = np.interp(gimbal.times, t, tr["target_angles"][:, 0]) / 2.0
        in_walk = (gimbal.times >= start) & (gimbal.times <= end)
        pointing = np.degrees(np.abs(gimbal.data[in_walk, 2] - half[in_walk]))
        lines = [f"active mirror (Fig. 4.40): camera {np.linalg.norm(camera - centre) / 1000:.1f} m from a "
                 f"{size / 1000:.1f} m mirror; a {2 * radius:.0f} mm target walks {settings['width'] / 1000:.2f} m "
                 f"at {settings['speed'] / 1000:.2f} m/s, {settings['range'] / 1000:.1f} m in front "
                 f"(peak {rate[walk].max():.1f} deg/s); {walk.sum()} camera frames at {settings['frame_rate']:g} Hz",
                 f"in mirror: {100 * tr['in_mirror'][walk].mean():.1f} % of frames",
                 f"a fixed {size / 1000:.1f} m mirror: {100 * fixed_in[walk].mean():.1f} % of frames; a fixed mirror "
                 f"would need {need:.2f} m (thesis: about {THESIS['fixed_mirror_m']:.0f} m, A-B of Fig. 4.40)",
                 f"mirror pointing error |theta_t - theta_v/2| while walking: {pointing.mean():.2f} deg mean, "
                 f"{pointing.max():.2f} deg max (gimbal {values['instrument']!r}, recorded mirror angle)"]
        if values["fixed"]:
            marks = session.stream(values["fixed"], "mark")
            seen = ~np.isnan(marks.data[(marks.times >= start) & (marks.times <= end), 0])
            lines.append(f"fixed detector {values['fixed']!r} (18.6 deg field): target seen in "
                         f"{100 * seen.mean():.1f} % of its scans during the walk")
        limits: dict[str, float] = {}
        if values["limits"]:
            limits = {k: math.degrees(tracking_limit(seed=values["seed"], faults=f)) for k, (_, f) in VARIANTS.items()}
            base = limits["default calibrated motor"]
            lines.append(f"tracking limit: {base:.1f} deg/s")
            lines.append(f"tracking limit of a target circling from rest (lost at E40), thesis: about "
                         f"{THESIS['limit']:.0f} deg/s (causes: motor torque for the mirror inertia, drive "
                         "stiffness, gear backlash; remedy: a stronger motor)")
            for label, value in limits.items():
                verdict = "" if value is base else (" rises" if value > base + RISE_DEG_S else " does not rise")
                lines.append(f"  {label:34s} {value:5.1f} deg/s{verdict}")
            if limits["backlash removed (BACKLASH H 0)"] <= base + RISE_DEG_S:
                lines.append("  (backlash: in this model the limit is the motor's acceleration budget against the "
                             "+-9.3 deg detector field; see docs/instruments/mirror_gimbal.md)")
        folder = figures_folder(session, values["figures"])
        figures = [self._walk_figure(folder / "active_mirror_walk.png", t, tr, fixed_in, gimbal.times,
                                     gimbal.data[:, 2])]
        if limits:
            figures.append(self._limit_figure(folder / "active_mirror_limits.png", limits))
        session.write_group(f"report/active_mirror_{root.rpartition('/')[2]}",
                            {"in_mirror_percent": 100 * tr["in_mirror"][walk].mean(),
                             "fixed_in_mirror_percent": 100 * fixed_in[walk].mean(), "fixed_mirror_m": need,
                             "limits_deg_s": np.array(list(limits.values()))},
                            {"limit_variants": list(limits), "truth": "/" + root})
        print("\n".join(lines) + "".join(f"\nfigure: {f}" for f in figures), flush=True)

    @staticmethod
    def _walk_figure(path: Path, t: np.ndarray, tr: Mapping[str, np.ndarray], fixed_in: np.ndarray,
                     gimbal_t: np.ndarray, gimbal_mirror: np.ndarray) -> Path:
        deg = np.degrees
        return plot_traces(path, [
            Panel("mirror angle against the ideal theta_v / 2", "session time (s)", "horizontal angle (deg)", [
                Trace(t, deg(tr["target_angles"][:, 0]) / 2, "ideal theta_v / 2 (truth)"),
                Trace(t, deg(tr["mirror_angles"][:, 0]), "active mirror theta_t (truth)", "--"),
                Trace(gimbal_t, deg(gimbal_mirror), "recorded mirror angle", "."),
                Trace(t, 0 * t, "fixed mirror", ":")]),
            Panel("the target's image inside the 1 m mirror, seen from the camera", "session time (s)",
                  "in mirror (1 = yes)", [Trace(t, tr["in_mirror"].astype(float), "active mirror"),
                                          Trace(t, fixed_in.astype(float) * 0.95, "fixed mirror (x 0.95)", "--")])],
            "active mirror: the walk of Fig. 4.40")

    @staticmethod
    def _limit_figure(path: Path, limits: Mapping[str, float]) -> Path:
        def curve(backlash: bool) -> tuple[list[float], list[float]]:
            rows = [(VARIANTS[k][0], v) for k, v in limits.items() if ("BACKLASH H 0" in VARIANTS[k][1]) != backlash]
            return [r[0] for r in rows], [r[1] for r in rows]

        return plot_traces(path, [Panel("tracking limit of a target circling from rest (lost at E40)",
                                        "motor torque limit (x the calibrated default)", "limit (deg/s)", [
                                            Trace(*curve(True), "simulated gimbal, calibrated backlash", "o-"),
                                            Trace(*curve(False), "simulated gimbal, backlash removed", "s--"),
                                            Trace([1.0, 2.0], [THESIS["limit"]] * 2, "thesis: about 15 deg/s",
                                                  ":")])],
                           "active mirror: tracking-rate limit")


STEPS = [ActiveMirrorReport]
