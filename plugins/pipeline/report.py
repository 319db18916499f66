"""The demo report: a session's measurements against its ``/truth``, printed and plotted.

Everything is read from the session file: the latest successful runs of ``reconstruct_mirror``,
``mirror_tracks``, ``mirror_normal``, ``rssr_markers`` and ``rssr_angles``, the camera group
``/calibration/<camera>``, and the ground truth ``/truth/<instrument>`` written by the virtual lab.
Truth is used only for the comparison. Tracks are matched to the truth's markers by the smallest
mean 3-D distance (``linear_sum_assignment``), then:

* 3-D RMS error per marker and the systematic error per axis (mean of measured − true over all
  frames and markers), printed beside the thesis's 1.3 / −6.9 / 10.9 mm (§3.6.1, Table 3.2);
* pairing: a pair is correct when its direct and its mirror image are, of all the frame's true
  images, nearest to that marker's direct and mirror image, within 3 px (truth pixels converted to
  the scanner frame with :func:`scan_pixels` and the truth's ``scan_first_line``);
* digitising error: every true image's nearest detection (``detect_markers`` on this instrument's
  frames) minus the true position, RMS and mean per axis in scanner px (x across, y along the feed);
* kinematics: RMS of measured minus analytic angular velocity and acceleration.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.figure import Figure
from mirrorlab.core import save_figure
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from .errors import PipelineError

if TYPE_CHECKING:
    from mirrorlab.core import Session

__all__ = ["THESIS_SYSTEMATIC_MM", "DemoReport", "DigitisingError", "angular_figure", "build_report",
           "digitising_error", "format_report", "kinematic_rms", "measured_frames", "pair_is_correct", "scan_pixels",
           "trajectories_figure", "write_figures"]

#: Systematic error per axis (X, Y, Z) of the thesis's RSSR mirror experiment, mm.
THESIS_SYSTEMATIC_MM = (1.3, -6.9, 10.9)
#: Scanner frame geometry: 512 px across, 384 lines for a whole 24 x 18 mm frame.
SCAN_WIDTH, SCAN_LINES = 512, 384
#: A detection farther than this from a true image is not its measurement (pairing check and
#: digitising error), px. The film path's worst image error is ~2 px, the markers are >= 10 px apart.
DIGITISE_GATE_PX = 3.0
#: Frames at each end whose acceleration is the smoothing spline's end condition (0), not measured.
ACCEL_END_FRAMES = 1

FloatArray = NDArray[np.float64]


def scan_pixels(xy: FloatArray, width: int, height: int, lines: int, first_line: float | None = None) -> FloatArray:
    """Truth pixels of a ``width`` x ``height`` render → pixels of the scanner frame with ``lines`` lines.

    The render is a whole 24 x 18 mm frame (512 px x 384 lines); the scanned frame starts at film
    line ``first_line`` (default: the central ``lines``, as the direct source crops them; the
    FSCAN digitiser starts ``head_skip`` lines after the frame edge, see the truth's
    ``scan_first_line`` attribute).

    Examples
    --------
    >>> scan_pixels(np.array([[1.5, 20.5]]), 1024, 768, 344).tolist()
    [[0.5, -10.0]]
    >>> scan_pixels(np.array([[1.5, 20.5]]), 1024, 768, 344, first_line=37).tolist()
    [[0.5, -27.0]]
    """
    top = (SCAN_LINES - lines) // 2 if first_line is None else first_line
    x = (xy[..., 0] + 0.5) * SCAN_WIDTH / width - 0.5
    y = (xy[..., 1] + 0.5) * SCAN_LINES / height - 0.5 - top
    return np.stack([x, y], axis=-1)


def pair_is_correct(real_xy: FloatArray, virtual_xy: FloatArray, true_real: FloatArray, true_virtual: FloatArray,
                    marker: int, gate: float = DIGITISE_GATE_PX) -> NDArray[np.bool_]:
    """Per frame: is (``real_xy``, ``virtual_xy``) the direct and mirror image of ``marker``?

    True when, among all true images of the frame (direct and mirror, every marker), the one
    nearest to ``real_xy`` is ``marker``'s direct image and the one nearest to ``virtual_xy`` is its
    mirror image, both within ``gate`` px. A pairing mistake swaps markers or views; the
    digitising error only moves the images by a fraction of a pixel.

    Parameters
    ----------
    real_xy, virtual_xy : (F, 2) the pair of one track per frame, px.
    true_real, true_virtual : (F, M, 2) true direct and mirror images, px (NaN not visible).

    Examples
    --------
    >>> tr, tv = np.array([[[0.0, 0], [10, 0]]]), np.array([[[50.0, 0], [60, 0]]])
    >>> pair_is_correct(np.array([[0.4, 0]]), np.array([[50.5, 0]]), tr, tv, 0).tolist()
    [True]
    >>> pair_is_correct(np.array([[0.4, 0]]), np.array([[59.5, 0]]), tr, tv, 0).tolist()
    [False]
    """
    M = true_real.shape[1]
    images = np.concatenate([true_real, true_virtual], axis=1)                    # (F, 2M, 2)

    def nearest(xy: FloatArray) -> tuple[NDArray[np.int64], FloatArray]:
        d = np.linalg.norm(xy[:, None] - images, axis=2)
        d = np.where(np.isfinite(d), d, np.inf)
        i = np.argmin(d, axis=1)
        return i, np.take_along_axis(d, i[:, None], axis=1)[:, 0]

    ir, dr = nearest(np.asarray(real_xy, float))
    iv, dv = nearest(np.asarray(virtual_xy, float))
    return (ir == marker) & (iv == M + marker) & (dr < gate) & (dv < gate)


@dataclass(frozen=True)
class DigitisingError:
    """Detected image positions against the truth's, in scanner pixels (x across, y along the feed).

    ``rms`` (2,) and ``systematic`` (2,) per axis (px), ``rms_2d`` (px), ``matched`` of ``visible``
    true images (direct and mirror) with a detection within ``gate`` px.
    """

    rms: FloatArray
    systematic: FloatArray
    rms_2d: float
    matched: int
    visible: int
    gate: float


def digitising_error(detected: FloatArray, true_xy: FloatArray, gate: float = DIGITISE_GATE_PX) -> DigitisingError:
    """Each true image's nearest detection (within ``gate`` px) minus the true position.

    Parameters
    ----------
    detected : (F, K, 2) detections per frame, NaN-padded, scanner px.
    true_xy : (F, V, 2) true image positions per frame (every view of every marker), NaN where not
        visible, scanner px.

    Examples
    --------
    >>> e = digitising_error(np.array([[[10.2, 5.0], [50.0, 7.1], [np.nan, np.nan]]]),
    ...                      np.array([[[50.0, 7.0], [10.0, 5.0], [200.0, 3.0]]]))
    >>> np.round(e.systematic, 3).tolist(), e.matched, e.visible
    ([0.1, 0.05], 2, 3)
    """
    visible = int(np.all(np.isfinite(true_xy), axis=2).sum())
    if detected.shape[1] == 0:
        detected = np.full((len(detected), 1, 2), np.nan)
    d = np.linalg.norm(detected[:, None] - true_xy[:, :, None], axis=3)          # (F, V, K)
    d = np.where(np.isfinite(d), d, np.inf)
    nearest = np.argmin(d, axis=2)
    ok = np.take_along_axis(d, nearest[..., None], axis=2)[..., 0] < gate
    e = (np.take_along_axis(detected, nearest[..., None], axis=1) - true_xy)[ok]  # (matched, 2)
    if not len(e):
        return DigitisingError(np.full(2, np.nan), np.full(2, np.nan), float("nan"), 0, visible, gate)
    return DigitisingError(np.sqrt(np.mean(e ** 2, axis=0)), e.mean(axis=0), float(np.sqrt(np.mean(np.sum(e ** 2, 1)))),
                           int(len(e)), visible, gate)


def measured_frames(key: str, frames: int) -> NDArray[np.bool_]:
    """Frames whose ``key`` (``theta_dot``, ``phi_ddot``...) is a measurement, not an end condition.

    The GCV smoothing spline that ``rssr_angles`` differentiates is a natural cubic spline: its
    second derivative is 0 at the first and last sample by construction, so the accelerations of
    the first and last :data:`ACCEL_END_FRAMES` frames are not measured. Velocities are.

    Examples
    --------
    >>> measured_frames("phi_ddot", 5).tolist(), measured_frames("phi_dot", 3).tolist()
    ([False, True, True, True, False], [True, True, True])
    """
    keep = np.ones(frames, bool)
    if key.endswith("_ddot"):
        keep[:ACCEL_END_FRAMES] = keep[frames - ACCEL_END_FRAMES:] = False
    return keep


def kinematic_rms(measured: dict[str, FloatArray], analytic: dict[str, FloatArray]) -> dict[str, float]:
    """RMS of measured minus analytic angular velocity (rad/s) and acceleration (rad/s²).

    Only measured frames count (:func:`measured_frames`: not the accelerations' end frames).

    Examples
    --------
    >>> a = {"phi_ddot": np.array([0.3, 0.1, 0.2, 0.3])}
    >>> kinematic_rms({"phi_ddot": np.array([0.0, 0.1, 0.2, 0.0])}, a)
    {'phi_ddot': 0.0}
    """
    out = {}
    for k in ("theta_dot", "phi_dot", "theta_ddot", "phi_ddot"):
        if k in analytic and k in measured:
            d = (measured[k] - analytic[k])[measured_frames(k, len(analytic[k]))]
            out[k] = float(np.sqrt(np.nanmean(d ** 2))) if np.isfinite(d).any() else float("nan")
    return out


@dataclass
class DemoReport:
    """Numbers of one demo run (all measured; truth used only as the reference)."""

    path: str
    labels: list[str]
    frames: int
    frame_period: float
    time: FloatArray
    measured: FloatArray            # (F, M, 3) mm, columns in truth marker order
    truth: FloatArray               # (F, M, 3) mm
    rms_per_marker: FloatArray      # (M,) mm
    frames_per_marker: NDArray[np.int64]
    systematic: FloatArray          # (3,) mm
    pairs_correct: int
    pairs_decided: int
    pairs_visible: int
    calibration_rms: float
    calibration_points: int
    calibration_model: str
    normal: FloatArray
    normal_angle: float             # rad, measured vs true normal
    kinematics: dict[str, FloatArray]
    analytic: dict[str, FloatArray]
    kinematic_rms: dict[str, float]
    digitising: DigitisingError | None = None
    source: str = ""
    figures: list[str] = field(default_factory=list)

    def store(self, session: Session) -> str:
        """Write the summary numbers to ``/report`` (``/report-2``... if present)."""
        name, n = "report", 1
        while session.exists(name):
            n += 1
            name = f"report-{n}"
        dg = self.digitising
        extra = {} if dg is None else {
            "digitising_rms": dg.rms, "digitising_systematic": dg.systematic,
            "digitising_images": np.array([dg.matched, dg.visible])}
        session.write_group(name, {**extra,
            "rms_per_marker": self.rms_per_marker, "systematic": self.systematic,
            "thesis_systematic": np.array(THESIS_SYSTEMATIC_MM), "frames_per_marker": self.frames_per_marker,
            "pairs": np.array([self.pairs_correct, self.pairs_decided, self.pairs_visible]),
            "kinematic_rms": np.array([self.kinematic_rms[k] for k in sorted(self.kinematic_rms)]),
        }, {"labels": list(self.labels), "kinematic_keys": sorted(self.kinematic_rms), "figures": list(self.figures),
            "units": "mm, rad/s, rad/s^2", "calibration_rms_mm": self.calibration_rms,
            "normal_angle_rad": self.normal_angle, "source": self.source,
            "digitising_units": "scanner px, (x across, y along the feed); images (matched, visible)",
            "description": "demo summary: measurements of this file against its /truth"})
        return "/" + name


def _latest(session: Session, algorithm: str) -> dict[str, Any]:
    runs = [r for r in session.results(algorithm) if r.status == "ok"]
    if not runs:
        raise PipelineError(f"the report needs a successful {algorithm} run in {session.path}; "
                            "run the recipe's earlier steps first")
    return session.result(runs[-1]).outputs


def build_report(session: Session, instrument: str) -> DemoReport:
    """Compare the latest reconstruction and kinematics of ``session`` with ``/truth/<instrument>``.

    Raises
    ------
    PipelineError
        A needed result or the truth group is missing, or frame counts disagree.
    """
    if not session.exists(f"truth/{instrument}/markers"):
        raise PipelineError(f"no /truth/{instrument} in {session.path}: the report compares against the virtual "
                            "lab's ground truth, so record the instrument with source = \"virtual\"")
    truth = session.truth(instrument)
    tg = session.attributes(f"truth/{instrument}/markers")
    true_pos = truth["markers/positions"]
    labels = [x.decode() if isinstance(x, bytes) else str(x) for x in truth["markers/labels"]]
    points = np.asarray(_latest(session, "reconstruct_mirror")["points"], float)
    if len(points) != len(true_pos):
        raise PipelineError(f"{len(points)} reconstructed frames but {len(true_pos)} truth frames in "
                            f"/truth/{instrument}; the report needs one reconstruction of the whole recording")
    F, T, M = points.shape[0], points.shape[1], true_pos.shape[1]
    dist = np.linalg.norm(points[:, :, None] - true_pos[:, None], axis=3)           # (F, T, M)
    cost = np.nan_to_num(np.nanmean(np.where(np.isfinite(dist), dist, np.nan), axis=0), nan=1e12) \
        if np.isfinite(dist).any() else np.full((T, M), 1e12)
    rows, cols = linear_sum_assignment(cost)
    measured = np.full((F, M, 3), np.nan)
    measured[:, cols] = points[:, rows]
    err = measured - true_pos
    have = np.all(np.isfinite(err), axis=2)
    with np.errstate(invalid="ignore"):
        rms = np.sqrt(np.nansum(np.sum(err ** 2, axis=2), axis=0) / np.maximum(have.sum(axis=0), 1))
    rms[have.sum(axis=0) == 0] = np.nan
    systematic = np.nanmean(err[have], axis=0) if have.any() else np.full(3, np.nan)

    # pairing against the truth's images (in scanner pixels)
    settings = session.json_attribute(f"instruments/{instrument}", "settings", {})
    lines = int(settings.get("lines", SCAN_LINES))
    w, h = int(tg["image_width"]), int(tg["image_height"])
    first = float(tg["scan_first_line"]) if "scan_first_line" in tg else None
    t_real = scan_pixels(truth["markers/real_xy"], w, h, lines, first)           # (F, M, 2)
    t_all = scan_pixels(truth["markers/virtual_xy"], w, h, lines, first)         # (F, K, M, 2)
    t_virt = t_all[:, 0]                                                        # mirror 0
    mt = _latest(session, "mirror_tracks")
    rxy, vxy = np.asarray(mt["real_xy"], float), np.asarray(mt["virtual_xy"], float)
    decided = np.all(np.isfinite(rxy), axis=2) & np.all(np.isfinite(vxy), axis=2)  # (F, T)
    correct = 0
    track_to_marker = dict(zip(rows.tolist(), cols.tolist(), strict=True))
    for t, m in track_to_marker.items():
        ok = pair_is_correct(rxy[:, t], vxy[:, t], t_real, t_virt, m)
        correct += int(np.sum(ok & decided[:, t]))
    visible = int(np.sum(truth["markers/real_visible"] & truth["markers/virtual_visible"][:, 0]))

    cal = {}
    for name in session.members("calibration"):
        group, held = f"calibration/{name}", session.members(f"calibration/{name}")
        cal = {"rms": float(np.asarray(session.read(f"{group}/rms"))) if "rms" in held else float("nan"),
               "points": int(session.node(f"{group}/residuals").shape[0]) if "residuals" in held else 0,
               "model": str(session.attributes(group).get("model", ""))}
    normal = np.asarray(_latest(session, "mirror_normal")["normal"], float).reshape(-1)[:3]
    true_normal = truth["mirrors/normal"][0] if session.exists(f"truth/{instrument}/mirrors") else np.full(3, np.nan)
    angle = float(np.arccos(np.clip(abs(normal @ true_normal) / np.linalg.norm(normal) / np.linalg.norm(true_normal),
                                    -1, 1)))

    detected = _detections(session, instrument)
    digitising = None if detected is None or len(detected) != F else digitising_error(
        detected, np.concatenate([t_real, t_all.reshape(F, -1, 2)], axis=1))

    kin = {k: np.asarray(v, float) for k, v in _latest(session, "rssr_angles").items()}
    markers = _latest(session, "rssr_markers")
    time = np.asarray(markers["time"], float)
    analytic = {k: truth[f"analytic/{k}"] for k in ("theta", "theta_dot", "theta_ddot", "phi", "phi_dot", "phi_ddot")
                if f"analytic/{k}" in truth}
    k_rms = kinematic_rms(kin, analytic)
    return DemoReport(str(session.path), labels, F, float(markers["frame_period"]), time, measured, true_pos, rms,
                      have.sum(axis=0).astype(np.int64), systematic, correct, int(decided.sum()), visible,
                      cal.get("rms", float("nan")), cal.get("points", 0), cal.get("model", ""), normal, angle,
                      kin, analytic, k_rms, digitising, str(tg.get("source", "")))


def _detections(session: Session, instrument: str) -> FloatArray | None:
    """``xy`` of the latest successful ``detect_markers`` run on ``instrument``'s frames, or ``None``."""
    frames = f"/instruments/{instrument}/frames/data"
    for ref in reversed([r for r in session.results("detect_markers") if r.status == "ok"]):
        data = session.result(ref)
        if str(data.attrs.get("inputs", {}).get("frames", "")).rstrip("/") == frames and "xy" in data.outputs:
            return np.asarray(data.outputs["xy"], float)
    return None


def format_report(r: DemoReport) -> str:
    """The printed summary (plain text)."""
    pct = 100.0 * r.pairs_correct / r.pairs_decided if r.pairs_decided else float("nan")
    lines = [
        f"RSSR mirror experiment: {r.frames} frames, {1 / r.frame_period:.3g} frames/s, {len(r.labels)} markers",
        f"  calibration    {r.calibration_model} plane map from {r.calibration_points} grid points, "
        f"residual RMS {r.calibration_rms:.3f} mm",
        f"  mirror normal  ({r.normal[0]:+.5f}, {r.normal[1]:+.5f}, {r.normal[2]:+.5f}), "
        f"{np.degrees(r.normal_angle):.3f} deg from the true mirror",
        f"  pairing        {r.pairs_correct}/{r.pairs_decided} pairs correct ({pct:.1f} %), "
        f"{r.pairs_decided}/{r.pairs_visible} visible pairs found",
    ]
    dg = r.digitising
    if dg is not None:
        chain = "film + line-scan digitiser" if r.source == "fscan" else "direct rendering"
        lines += [
            f"  digitising error ({chain}): detected - true image positions, scanner px",
            f"    {dg.matched}/{dg.visible} images within {dg.gate:g} px      across (x)   along feed (y)",
            f"    RMS {dg.rms_2d:6.3f} px                       {dg.rms[0]:8.3f}   {dg.rms[1]:8.3f} px",
            f"    systematic (mean)                      {dg.systematic[0]:+8.3f}   {dg.systematic[1]:+8.3f} px",
        ]
    lines += [
        "  3-D RMS error per marker (against /truth):",
    ]
    for label, e, n in zip(r.labels, r.rms_per_marker, r.frames_per_marker, strict=True):
        lines.append(f"    {label:<6} {e:8.3f} mm   ({n} frames)")
    sx, sy, sz = r.systematic
    tx, ty, tz = THESIS_SYSTEMATIC_MM
    lines += [
        "  systematic error per axis (mean measured - true):   X         Y         Z",
        f"    this run                                     {sx:+8.3f}  {sy:+8.3f}  {sz:+8.3f} mm",
        f"    thesis (film, 1984)                          {tx:+8.1f}  {ty:+8.1f}  {tz:+8.1f} mm",
        f"  kinematics, RMS of measured - analytic (accelerations without {ACCEL_END_FRAMES} frame(s) at each "
        "end: the spline's end condition sets them to 0):",
    ]
    for k, unit in (("theta_dot", "rad/s"), ("phi_dot", "rad/s"), ("theta_ddot", "rad/s²"), ("phi_ddot", "rad/s²")):
        if k in r.kinematic_rms:
            scale = float(np.sqrt(np.nanmean(r.analytic[k][measured_frames(k, len(r.analytic[k]))] ** 2)))
            lines.append(f"    {k:<11} {r.kinematic_rms[k]:.4f} {unit:<7} (analytic RMS {scale:.4f})")
    lines.append("  figures:")
    lines += [f"    {p}" for p in r.figures]
    return "\n".join(lines)


def trajectories_figure(r: DemoReport) -> Figure:
    """X, Y and Z (mm) of every marker over time (s): measured points over the true curves."""
    fig = Figure(figsize=(8, 8), layout="constrained")
    axes = fig.subplots(3, 1, sharex=True)
    for a, axis in enumerate("XYZ"):
        for m, label in enumerate(r.labels):
            line, = axes[a].plot(r.time, r.truth[:, m, a], "-", lw=1.2, label=f"{label} true")
            axes[a].plot(r.time, r.measured[:, m, a], "o", ms=3.5, color=line.get_color(), label=f"{label} measured")
        axes[a].set_ylabel(f"{axis} (mm)")
        axes[a].grid(alpha=0.3)
    axes[0].legend(ncol=2, fontsize=8)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("RSSR spherical joints: measured (mirror method) vs true")
    return fig


def angular_figure(r: DemoReport) -> Figure:
    """Input and output angular velocity (rad/s) and acceleration (rad/s²) over time (s).

    Measured values against the analytic motion and the model evaluated at the measured θ. The
    accelerations of the end frames (:func:`measured_frames`) are drawn hollow: they are the
    spline's end condition, not measurements, and are left out of the printed RMS.

    The panels of a row share one y scale that includes zero, so the crank's nearly constant
    θ̇ is not blown up into a curve of its noise; each panel's title states its RMS deviation
    from the analytic value instead. The analytic motion is a wide grey band with the model drawn over it
    dashed, so the model stays visible where the two coincide.
    """
    fig = Figure(figsize=(10, 7), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True, sharey="row")
    panels = (("theta_dot", "input crank", "θ̇ (rad/s)", "rad/s"), ("phi_dot", "output rocker", "φ̇ (rad/s)", "rad/s"),
              ("theta_ddot", "input crank", "θ̈ (rad/s²)", "rad/s²"), ("phi_ddot", "output rocker", "φ̈ (rad/s²)", "rad/s²"))
    for ax, (k, title, ylabel, unit) in zip(axes.ravel(), panels, strict=True):
        if k in r.analytic:
            ax.plot(r.time, r.analytic[k], "-", color="0.6", lw=4.0, solid_capstyle="butt", zorder=2.0,
                    label="analytic")
        if "model_" + k in r.kinematics:
            ax.plot(r.time, r.kinematics["model_" + k], "--", color="C1", lw=1.5, zorder=2.5,
                    label="model at measured θ")
        if k in r.kinematics:
            keep = measured_frames(k, len(r.kinematics[k]))
            ax.plot(r.time[keep], r.kinematics[k][keep], "o", color="C0", ms=3.5, zorder=3.0, label="measured")
            if not keep.all():
                ax.plot(r.time[~keep], r.kinematics[k][~keep], "o", mfc="none", color="C0", ms=5, zorder=3.0,
                        label="end frames: spline end condition (not in RMS)")
        if k in r.kinematic_rms:
            title += f"\nRMS of measured − analytic: {r.kinematic_rms[k]:.2g} {unit}"
        ax.axhline(0.0, color="0.3", lw=0.6, zorder=1.0)      # zero in every row's range, drawn as a reference
        ax.set_title(title, fontsize=10)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    handles = {h.get_label(): h for ax in axes.ravel() for h in ax.get_lines() if not h.get_label().startswith("_")}
    fig.legend(list(handles.values()), list(handles), loc="outside lower center", ncol=len(handles), fontsize=8)
    fig.suptitle("RSSR angular velocity and acceleration: measured vs analytic")
    return fig


def write_figures(r: DemoReport, folder: str | Path) -> list[str]:
    """``trajectories.png`` (:func:`trajectories_figure`) and ``angular.png`` (:func:`angular_figure`)
    in ``folder``; returns their paths."""
    return [str(save_figure(fig, Path(folder) / name, dpi=110))
            for name, fig in (("trajectories.png", trajectories_figure(r)), ("angular.png", angular_figure(r)))]
