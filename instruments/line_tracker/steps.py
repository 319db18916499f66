"""``turntable_report``: the line tracker on the turntable (Fig. 4.35), next to the thesis.

Reads the recorded ``mark`` stream and the shared world's truth, fits the sinusoid of the
turntable's period (:mod:`.experiments`), prints it beside the thesis's ±251 px at 78.8 ms and
writes a PNG figure next to the session.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import Parameter, ParameterSet, Step, figures_folder
from mirrorlab.instruments.virtual_lab.figures import Panel, Trace, plot_traces
from mirrorlab.instruments.virtual_lab.line_sensor.sensor import CENTRE_PX, FOCAL_MM, PITCH_MM, angle_to_pixel
from mirrorlab.instruments.virtual_lab.worlds import latest_truth, truth_arrays

from .experiments import SinusoidFit, fit_sinusoid, uncut

if TYPE_CHECKING:
    from mirrorlab.core import Session

#: Fig. 4.35 and §3.4: amplitude (px, printed and as corrected in spec §6.11), sample period (s), samples per turn.
THESIS = {"amplitude": 251.0, "sample_period": 0.0788, "samples": 23.4}


#: Legend of the scans left out of the fit.
CLIPPED = "clipped scans: run cut by the sensor's end (not fitted)"


def turntable_panels(t: np.ndarray, m: np.ndarray, d: np.ndarray, fit: SinusoidFit, period: float,
                     truth_t: np.ndarray, truth_px: np.ndarray) -> list[Panel]:
    """The marks ``m`` (px) and run sizes ``d`` (px) at times ``t`` (s) with the sinusoid ``fit`` of
    ``period`` (s) and the truth ``truth_px`` at ``truth_t``.

    The scans whose run touches a sensor end (:func:`.experiments.uncut`) are left out of the fit:
    their centre and size are biased (the marks fall short of the peaks), so they are drawn apart.
    """
    whole = uncut(m, d)
    clipped = ~whole & np.isfinite(m)
    tt = np.asarray(truth_t, float)
    w = 2 * np.pi / period
    return [
        Panel("mark position on the line sensor", "session time (s)", "pixel (px)", [
            Trace(t[whole], m[whole], "recorded mark m (fitted)", "o"),
            Trace(t[clipped], m[clipped], CLIPPED, "x", size=6.0),
            Trace(tt, fit.centre + fit.amplitude * np.sin(w * tt + fit.phase), f"fitted sinusoid +-{fit.amplitude:.1f} px"),
            Trace(tt, truth_px, "truth", "--")]),
        Panel("mark size (adaptive threshold off)", "session time (s)", "run size d (px)",
              [Trace(t, d, "recorded d", ".-"), Trace(t[clipped], d[clipped], CLIPPED, "x", size=6.0)])]


class TurntableReport(Step):
    """``action = "turntable_report"``: the recorded turntable trace against Fig. 4.35 and the truth."""

    name = "turntable_report"
    version = "1.0.0"
    description = "fit the line tracker's turntable trace (amplitude, period) and print it next to Fig. 4.35; PNG"
    parameters = ParameterSet(
        Parameter("instrument", str, "tracker", help="the simulated line_tracker watching the turntable"),
        Parameter("period", float, 1.84, unit="s", bounds=(0.01, 3600.0), help="the turntable's period"),
        Parameter("figures", str, "", output="folder", help="folder for the PNG figures (default: <session>-figures)"),
    )

    instrument_keys = ("instrument",)

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        marks = session.stream(values["instrument"], "mark")
        t, m, d = marks.times, marks.data[:, 0], marks.data[:, 1]
        fit = fit_sinusoid(t, m, d, values["period"])
        root = latest_truth(session)
        tr = truth_arrays(session, root)
        expected = angle_to_pixel(np.interp(t, tr["time"], tr["target_angles"][:, 0]))
        off = np.abs(m - expected)[uncut(m, d)]
        lit, dark = d[m < CENTRE_PX - 55], d[m > CENTRE_PX + 55]
        corrected = 160.0 * FOCAL_MM / PITCH_MM / 1000.0
        lines = [f"turntable (Fig. 4.35): line tracker {values['instrument']!r}, {t[-1] - t[0]:.1f} s recorded "
                 f"through its driver, {fit.used} of {t.size} scans fitted",
                 f"sample period: {1000 * fit.sample_period:.2f} ms (thesis: {1000 * THESIS['sample_period']:.1f} ms "
                 "at 6.5 kHz)",
                 f"samples per turn: {fit.samples_per_cycle:.1f} (thesis: {THESIS['samples']})",
                 f"amplitude: +-{fit.amplitude:.2f} px (thesis: +-{THESIS['amplitude']:.0f} px; "
                 f"0.16 x 44 / 0.028 = {corrected:.1f} px, spec §6.11)",
                 f"centre {fit.centre:.1f} px, residual {fit.rms:.2f} px RMS; against /{root}: "
                 f"{np.median(off):.2f} px median, {off.max():.2f} px max (whole runs; a few ms of "
                 "stamping delay at up to 860 px/s)",
                 f"run size: {np.nanmean(lit):.0f} px on the lit side, {np.nanmean(dark):.0f} px on the dark side "
                 "(Fig. 4.34: wider on the lit side)"]
        tt = np.linspace(t[0], t[-1], 800)
        truth_px = angle_to_pixel(np.interp(tt, tr["time"], tr["target_angles"][:, 0]))
        figure = plot_traces(figures_folder(session, values["figures"]) / "turntable_trace.png",
                             turntable_panels(t, m, d, fit, values["period"], tt, truth_px),
                             "line tracker on the turntable (Fig. 4.35)")
        session.write_group(f"report/turntable_{root.rpartition('/')[2]}",
                            {"amplitude_px": fit.amplitude, "sample_period_s": fit.sample_period,
                             "centre_px": fit.centre, "rms_px": fit.rms},
                            {"instrument": values["instrument"], "truth": "/" + root})
        print("\n".join(lines) + f"\nfigure: {figure}", flush=True)


STEPS = [TurntableReport]
