"""Every figure the project writes has a title, labelled axes with units and a legend (issue 8, item 12),
and does not mislead (issue 19).

Each figure-producing function's matplotlib ``Figure`` is drawn from small inputs and inspected:
a title (figure or every panel), a y label with a unit ``(…)`` on every panel with data, an x
label with a unit on the bottom panel of every column, a legend naming every labelled artist, and
no legend drawn over a data point (the figure is laid out and drawn, then every legend's box is
compared with every visible data point in display coordinates). Figure-specific checks follow:
ranges that include zero, lines that stay visible over each other, marked points left out of a
fit, a marker drawn on top, consistent units.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from mirrorlab.instruments.line_tracker.experiments import fit_sinusoid, uncut
from mirrorlab.instruments.line_tracker.steps import CLIPPED, turntable_panels
from mirrorlab.instruments.ultrasonic_tracker.steps import search_panel
from mirrorlab.instruments.virtual_lab.figures import Panel, Trace, traces_figure
from mirrorlab.instruments.virtual_lab.line_sensor.sensor import PIXELS
from mirrorlab.plugins.kinematics import figures as kin
from mirrorlab.plugins.mechanisms import figures as mech
from mirrorlab.plugins.mechanisms.fourbar import LINK_NAMES, reconstruct_four_bar
from mirrorlab.plugins.mechanisms.synthetic import four_bar_markers
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


def four_bar_figure() -> Figure:
    """The thesis four-bar's 30 frames (noiseless, 9 markers filling the plane) reconstructed and drawn."""
    fit = reconstruct_four_bar(four_bar_markers(noise="none", shuffle=False)[0])
    link = np.full(fit.tracks.shape[1], -1)
    for k, name in enumerate(LINK_NAMES):
        link[list(fit.links[name])] = k
    return mech.four_bar_figure(fit.tracks, link, fit.joints)


#: The turntable's period (s), the line tracker's sample period (s) and the mark's run size (px):
#: Fig. 4.35's +-251 px sinusoid about the sensor's centre, so the runs at its peaks touch the ends.
PERIOD, SAMPLE, RUN = 1.84, 0.0788, 60.0


def turntable() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Marks ``m`` and run sizes ``d`` (px) at times ``t`` (s) of three turns, the runs cut at the sensor's ends."""
    t = np.arange(0.0, 3 * PERIOD, SAMPLE)
    centre = (PIXELS - 1) / 2 + 251.0 * np.sin(2 * np.pi * t / PERIOD)
    lo, hi = np.clip(centre - RUN / 2, 0.0, PIXELS - 1), np.clip(centre + RUN / 2, 0.0, PIXELS - 1)
    return t, (lo + hi) / 2, hi - lo


def turntable_figure() -> Figure:
    t, m, d = turntable()
    tt = np.linspace(t[0], t[-1], 400)
    return traces_figure(turntable_panels(t, m, d, fit_sinusoid(t, m, d, PERIOD), PERIOD, tt,
                                          (PIXELS - 1) / 2 + 251.0 * np.sin(2 * np.pi * tt / PERIOD)), "turntable")


def search_figure() -> Figure:
    """A search from 12 deg that ends in a cluster of platform positions around the target."""
    k = np.arange(40)
    theta = np.c_[0.3 * np.sin(k), np.minimum(12.0, 0.6 * k)] + np.where(k[:, None] > 20, 0.4 * np.c_[np.cos(k), np.sin(k)], 0)
    return traces_figure([search_panel(theta, np.array([0.0, 12.0]))], "search")


WALL_NODES = 0.05 * np.arange(61)
#: A wall like the optimal one: on the y axis below 1, a bulge to 0.355 at 2.4 and the polyline's first node out.
WALL = np.interp(WALL_NODES, [0.0, 1.0, 2.4, 2.9, 2.95, 3.0], [0.0, 0.0, 0.355, 0.19, 0.2, 0.0])


def walls_figure() -> Figure:
    y = np.linspace(0.0, 3.0, 301)
    return mech.walls_figure({"vertical wall": (0 * y, y), "optimal wall": (WALL, WALL_NODES)}, polylines=["optimal wall"])


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
    "mechanisms four_bar.png": four_bar_figure,
    "mechanisms walls.png": walls_figure,
    "line tracker turntable_trace.png": turntable_figure,
    "ultrasonic search.png": search_figure,
}


def drawn(fig: Figure) -> Figure:
    """``fig`` laid out and drawn on an Agg canvas (as when saved), so that extents are final."""
    FigureCanvasAgg(fig).draw()
    return fig


def visible_points(ax: Axes) -> np.ndarray:
    """Display coordinates (px) of every data point of ``ax``'s lines and collections inside the axes."""
    points = [line.get_transform().transform(line.get_xydata()) for line in ax.lines
              if line.get_visible() and len(line.get_xydata())]
    points += [c.get_offset_transform().transform(c.get_offsets()) for c in ax.collections
               if c.get_visible() and len(c.get_offsets())]
    xy = np.concatenate(points) if points else np.empty((0, 2))
    xy = xy[np.isfinite(xy).all(axis=1)]
    box = ax.get_window_extent()
    return xy[(xy[:, 0] >= box.x0) & (xy[:, 0] <= box.x1) & (xy[:, 1] >= box.y0) & (xy[:, 1] <= box.y1)]


def lines_by_label(ax: Axes) -> dict[str, Line2D]:
    return {line.get_label(): line for line in ax.lines}


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


@pytest.mark.parametrize("name", FIGURES)
def test_legend_covers_no_data(name: str) -> None:
    fig = drawn(FIGURES[name]())
    legends = [*fig.legends, *(ax.get_legend() for ax in fig.axes if ax.get_legend() is not None)]
    for legend in legends:
        box = legend.get_window_extent()
        for ax in fig.axes:
            xy = visible_points(ax)
            covered = (xy[:, 0] > box.x0) & (xy[:, 0] < box.x1) & (xy[:, 1] > box.y0) & (xy[:, 1] < box.y1)
            assert not covered.any(), f"{name}: the legend covers {covered.sum()} data points of {ax.get_title()!r}"


def test_angular_velocity_ranges_include_zero_and_the_model_stays_visible() -> None:
    """The crank's θ̇ is nearly constant: a range without zero would blow its noise up into a curve."""
    fig = drawn(angular_figure(demo_report()))
    for ax in fig.axes:
        lo, hi = ax.get_ylim()
        assert lo <= 0.0 <= hi, f"{ax.get_ylabel()}: y range {lo:.3g}..{hi:.3g} without zero"
        lines = lines_by_label(ax)
        if "model at measured θ" in lines:
            model, analytic = lines["model at measured θ"], lines["analytic"]
            # drawn over the analytic line, and told apart where the two coincide
            assert model.get_zorder() > analytic.get_zorder()
            assert model.get_linestyle() != analytic.get_linestyle() and model.get_color() != analytic.get_color()
            assert analytic.get_linewidth() > model.get_linewidth()
    crank, rocker = fig.axes[0], fig.axes[1]
    assert crank.get_ylim() == rocker.get_ylim()            # velocities to one scale, accelerations to another
    assert "RMS" in crank.get_title()                      # the deviation, no longer read off the range


def test_turntable_marks_the_clipped_scans_left_out_of_the_fit() -> None:
    t, m, d = turntable()
    left_out = ~uncut(m, d)
    assert 0 < left_out.sum() < t.size
    fig = turntable_figure()
    marks, size = (lines_by_label(ax) for ax in fig.axes)
    for ax_lines, values in ((marks, m), (size, d)):
        clipped = ax_lines[CLIPPED]
        np.testing.assert_array_equal(clipped.get_xdata(), t[left_out])
        np.testing.assert_array_equal(clipped.get_ydata(), values[left_out])
    fitted = marks["recorded mark m (fitted)"]
    np.testing.assert_array_equal(fitted.get_xdata(), t[~left_out])
    assert marks[CLIPPED].get_marker() != fitted.get_marker()


def test_search_target_is_drawn_on_top() -> None:
    ax = search_figure().axes[0]
    target = lines_by_label(ax)["target (truth)"]
    others = [line for line in ax.lines if line is not target]
    assert all(target.get_zorder() > line.get_zorder() for line in others)
    assert all(target.get_marker() != line.get_marker() and target.get_markersize() > 2 * line.get_markersize()
               for line in others)


def test_derivatives_are_in_mm() -> None:
    """Positions in mm with speeds in mm/s and accelerations in mm/s², not m/s: one unit of length."""
    fig = kin.derivatives_figure(t, ["A", "B"], xyz, 2 * xyz, 3 * xyz)
    units = [UNIT.search(ax.get_ylabel()).group() for ax in fig.axes]
    assert units == ["(mm)", "(mm/s)", "(mm/s²)"]
    for ax, scale in zip(fig.axes[1:], (2, 3), strict=True):
        np.testing.assert_array_equal(ax.lines[0].get_ydata(), np.linalg.norm(scale * xyz[:, 0], axis=-1))


def test_polyline_wall_shows_its_nodes() -> None:
    """The optimal wall is a polyline: its nodes are marked and the first node's hook is pointed out."""
    ax = walls_figure().axes[0]
    wall = next(line for line in ax.lines if line.get_label().startswith("optimal wall"))
    assert wall.get_marker() not in ("None", "", None) and len(wall.get_xdata()) == len(WALL_NODES)
    (note,) = ax.texts
    assert tuple(note.xy) == (WALL[-2], WALL_NODES[-2])
