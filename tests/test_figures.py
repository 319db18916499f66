"""Every figure the project writes has a title, labelled axes with units and a legend (issue 8, item 12).

Each figure-producing function's matplotlib ``Figure`` is drawn from small inputs and inspected:
a title (figure or every panel), a y label with a unit ``(…)`` on every panel with data, an x
label with a unit on the bottom panel of every column, and a legend naming every labelled artist.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import numpy as np
import pytest
from matplotlib.figure import Figure
from mirrorlab.instruments.virtual_lab.figures import Panel, Trace, traces_figure
from mirrorlab.plugins.kinematics import figures as kin
from mirrorlab.plugins.photogrammetry import figures as pg
from mirrorlab.plugins.pipeline.report import (
    ACCEL_END_FRAMES,
    DemoReport,
    angular_figure,
    kinematic_rms,
    measured_frames,
    trajectories_figure,
)

from tests.tolerances import roundoff

UNIT = re.compile(r"\(.+\)")


def demo_report(frames: int = 12) -> DemoReport:
    """A report as the demo builds it, with the natural spline's zero end accelerations."""
    t = np.arange(frames) / 3.0
    truth = np.stack([np.c_[300 + 60 * np.cos(t), 60 * np.sin(t), 700 + 0 * t],
                      np.c_[120 + 10 * np.cos(t), -250 + 30 * np.sin(t), 600 + 50 * np.cos(t)]], axis=1)
    analytic = {"theta_dot": np.full(frames, 0.58), "theta_ddot": np.zeros(frames),
                "phi_dot": 0.3 * np.sin(t), "phi_ddot": 0.3 * np.cos(t)}
    kinematics = {k: v + 0.01 for k, v in analytic.items()}
    for k in ("theta_ddot", "phi_ddot"):
        kinematics[k][[0, -1]] = 0.0
    kinematics["model_phi_dot"], kinematics["model_phi_ddot"] = analytic["phi_dot"], analytic["phi_ddot"]
    return DemoReport("demo.h5", ["S_A", "S_C"], frames, 1 / 3, t, truth + 0.5, truth, np.full(2, 0.5),
                      np.full(2, frames), np.full(3, 0.5), 2 * frames, 2 * frames, 2 * frames, 0.4, 700,
                      "projective", np.array([0.64, 0.0, 0.77]), 0.0004, kinematics, analytic,
                      kinematic_rms(kinematics, analytic))


t = np.linspace(0.0, 2.0, 30)
xyz = np.stack([np.c_[t, t ** 2, 0 * t], np.c_[t, -t, t]], axis=1)
FIGURES: dict[str, Callable[[], Figure]] = {
    "tracker traces": lambda: traces_figure([Panel("search", "theta1 (deg)", "theta2 (deg)", [Trace(t, t, "path")]),
                                             Panel("stage", "time (s)", "angle (deg)", [Trace(t, t, "target")])],
                                            "tracker"),
    "demo trajectories.png": lambda: trajectories_figure(demo_report()),
    "demo angular.png": lambda: angular_figure(demo_report()),
    "kinematics derivatives.png": lambda: kin.derivatives_figure(t, ["A", "B"], xyz, xyz, xyz),
    "kinematics angles.png": lambda: kin.angles_figure(t, {"theta3": t, "shoulder": np.c_[t, t, t]},
                                                       reference={"theta3": (t, 57.3 * t)}),
    "kinematics angles.png, one angle": lambda: kin.angles_figure(t, {"theta3": t}),
    "kinematics rigid.png": lambda: kin.rigid_figure(t, np.c_[t, t, t], rms=t, H=np.c_[t, t, t]),
    "photogrammetry min shooting distance": lambda: pg.min_shooting_distance_figure([0.0, 0.5], [0.1, 0.2],
                                                                                    [[1.0, 2.0], [1.5, 2.5]]),
    "photogrammetry error map": lambda: pg.error_map_figure(np.eye(3), 0.1 * np.eye(3)),
    "photogrammetry mirror angle sweep": lambda: pg.mirror_angle_sweep_figure([0.5, 0.7, 0.9], [2.0, 1.0, 2.0]),
}


@pytest.mark.parametrize("name", FIGURES)
def test_figure_is_labelled(name: str) -> None:
    fig = FIGURES[name]()
    panels = [ax for ax in fig.axes if ax.get_visible() and (ax.lines or ax.collections)]
    assert panels, name
    title = fig._suptitle.get_text() if fig._suptitle is not None else ""
    assert title or all(ax.get_title() for ax in panels), f"{name}: no title"
    for ax in panels:
        assert UNIT.search(ax.get_ylabel()), f"{name}: y label {ax.get_ylabel()!r} without a unit"
    columns: dict[float, list] = {}
    for ax in panels:
        columns.setdefault(round(ax.get_position().x0, 3), []).append(ax)
    for column in columns.values():
        bottom = min(column, key=lambda ax: ax.get_position().y0)
        assert UNIT.search(bottom.get_xlabel()), f"{name}: x label {bottom.get_xlabel()!r} without a unit"
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)]
    assert legends, f"{name}: no legend"
    shown = {text.get_text() for legend in legends for text in legend.get_texts()}
    labelled = {a.get_label() for ax in panels for a in (*ax.lines, *ax.collections)
                if not a.get_label().startswith("_")}
    assert labelled <= shown, f"{name}: not in a legend: {sorted(labelled - shown)}"


def test_end_accelerations_are_left_out_of_the_rms() -> None:
    """The natural spline's end accelerations are 0 by construction: not measured, not counted."""
    r = demo_report()
    # (v + 0.01) - v rounds at the scale of v (<= 0.59), then squares, a mean over the frames, a root
    tol = roundoff(scale=0.59, ops=r.frames)
    assert r.kinematic_rms["phi_ddot"] == pytest.approx(0.01, abs=tol)
    assert r.kinematic_rms["theta_dot"] == pytest.approx(0.01, abs=tol)

    keep = measured_frames("phi_ddot", r.frames)
    assert ACCEL_END_FRAMES == 1 and keep.sum() == r.frames - 2 and not keep[0] and not keep[-1]


def test_end_frames_are_drawn_apart_from_the_measurements() -> None:
    fig = angular_figure(demo_report())
    for ax in fig.axes[2:]:          # the acceleration panels
        by_label = {line.get_label(): line for line in ax.lines}
        assert len(by_label["measured"].get_xdata()) == 12 - 2
        ends = by_label["end frames: spline end condition (not in RMS)"]
        assert ends.get_markerfacecolor() == "none" and len(ends.get_xdata()) == 2
