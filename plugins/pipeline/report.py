"""The demo report: a session's measurements against its ``/truth``, printed and plotted.

Everything is read from the session file: the latest successful runs of ``reconstruct_mirror``,
``mirror_tracks``, ``mirror_normal``, ``rssr_markers`` and ``rssr_angles``, the camera group
``/calibration/<camera>``, and the ground truth ``/truth/<instrument>`` written by the virtual lab.
Truth is used only for the comparison. Tracks are matched to the truth's markers by the smallest
mean 3-D distance (``linear_sum_assignment``), then:

* 3-D RMS error per marker and the systematic error per axis (mean of measured − true over all
  frames and markers), printed beside the thesis's 1.3 / −6.9 / 10.9 mm (§3.6.1, Table 3.2);
* pairing: a pair is correct when both its direct and mirror image lie within 1 px of the truth's
  images of that marker (truth pixels converted to the scanner frame: resized to 512 x 384, the
  central ``lines`` rows kept);
* kinematics: RMS of measured minus analytic angular velocity and acceleration.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core.store import schema
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from .errors import PipelineError

if TYPE_CHECKING:
    from mirrorlab.core.session import Session

__all__ = ["THESIS_SYSTEMATIC_MM", "DemoReport", "build_report", "format_report", "scan_pixels", "write_figures"]

#: Systematic error per axis (X, Y, Z) of the thesis's RSSR mirror experiment, mm.
THESIS_SYSTEMATIC_MM = (1.3, -6.9, 10.9)
#: Scanner frame geometry: 512 px across, 384 lines for a whole 24 x 18 mm frame.
SCAN_WIDTH, SCAN_LINES = 512, 384
PAIR_TOL_PX = 1.0

FloatArray = NDArray[np.float64]


def scan_pixels(xy: FloatArray, width: int, height: int, lines: int) -> FloatArray:
    """Truth pixels of a ``width`` x ``height`` render → pixels of the scanner frame with ``lines`` lines.

    Examples
    --------
    >>> scan_pixels(np.array([[1.5, 20.5]]), 1024, 768, 344).tolist()
    [[0.5, -10.0]]
    """
    x = (xy[..., 0] + 0.5) * SCAN_WIDTH / width - 0.5
    y = (xy[..., 1] + 0.5) * SCAN_LINES / height - 0.5 - (SCAN_LINES - lines) // 2
    return np.stack([x, y], axis=-1)


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
    figures: list[str] = field(default_factory=list)

    def store(self, session: Session) -> str:
        """Write the summary numbers to ``/report`` (``/report-2``... if present)."""
        name, n = "report", 1
        while name in session.file:
            n += 1
            name = f"report-{n}"
        session.write_group(name, {
            "rms_per_marker": self.rms_per_marker, "systematic": self.systematic,
            "thesis_systematic": np.array(THESIS_SYSTEMATIC_MM), "frames_per_marker": self.frames_per_marker,
            "pairs": np.array([self.pairs_correct, self.pairs_decided, self.pairs_visible]),
            "kinematic_rms": np.array([self.kinematic_rms[k] for k in sorted(self.kinematic_rms)]),
        }, {"labels": list(self.labels), "kinematic_keys": sorted(self.kinematic_rms), "figures": list(self.figures),
            "units": "mm, rad/s, rad/s^2", "calibration_rms_mm": self.calibration_rms,
            "normal_angle_rad": self.normal_angle,
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
    f = session.file
    if f"truth/{instrument}/markers" not in f:
        raise PipelineError(f"no /truth/{instrument} in {session.path}: the report compares against the virtual "
                            "lab's ground truth, so record the instrument with source = \"virtual\"")
    tg = f[f"truth/{instrument}/markers"]
    true_pos = tg["positions"][()]
    labels = [x.decode() if isinstance(x, bytes) else str(x) for x in tg["labels"][()]]
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
    settings = schema.get_json(f[f"instruments/{instrument}"], "settings", {})
    lines = int(settings.get("lines", SCAN_LINES))
    w, h = int(tg.attrs["image_width"]), int(tg.attrs["image_height"])
    t_real = scan_pixels(tg["real_xy"][()], w, h, lines)                        # (F, M, 2)
    t_virt = scan_pixels(tg["virtual_xy"][()][:, 0], w, h, lines)               # (F, M, 2), mirror 0
    mt = _latest(session, "mirror_tracks")
    rxy, vxy = np.asarray(mt["real_xy"], float), np.asarray(mt["virtual_xy"], float)
    decided = np.all(np.isfinite(rxy), axis=2) & np.all(np.isfinite(vxy), axis=2)  # (F, T)
    correct = 0
    track_to_marker = dict(zip(rows.tolist(), cols.tolist(), strict=True))
    for t, m in track_to_marker.items():
        ok = (np.linalg.norm(rxy[:, t] - t_real[:, m], axis=1) < PAIR_TOL_PX) & \
             (np.linalg.norm(vxy[:, t] - t_virt[:, m], axis=1) < PAIR_TOL_PX)
        correct += int(np.sum(ok & decided[:, t]))
    visible = int(np.sum(tg["real_visible"][()] & tg["virtual_visible"][()][:, 0]))

    cal = {}
    for name in f.get("calibration", {}):
        cal = {"rms": float(np.asarray(f[f"calibration/{name}/rms"][()])) if "rms" in f[f"calibration/{name}"]
               else float("nan"),
               "points": int(len(f[f"calibration/{name}/residuals"])) if "residuals" in f[f"calibration/{name}"]
               else 0,
               "model": schema.attr_str(f[f"calibration/{name}"], "model")}
    normal = np.asarray(_latest(session, "mirror_normal")["normal"], float).reshape(-1)[:3]
    true_normal = f[f"truth/{instrument}/mirrors/normal"][()][0] if f"truth/{instrument}/mirrors" in f \
        else np.full(3, np.nan)
    angle = float(np.arccos(np.clip(abs(normal @ true_normal) / np.linalg.norm(normal) / np.linalg.norm(true_normal),
                                    -1, 1)))

    kin = {k: np.asarray(v, float) for k, v in _latest(session, "rssr_angles").items()}
    markers = _latest(session, "rssr_markers")
    time = np.asarray(markers["time"], float)
    ag = f[f"truth/{instrument}/analytic"]
    analytic = {k: ag[k][()] for k in ("theta", "theta_dot", "theta_ddot", "phi", "phi_dot", "phi_ddot") if k in ag}
    k_rms = {}
    for k in ("theta_dot", "phi_dot", "theta_ddot", "phi_ddot"):
        if k in analytic and k in kin:
            d = kin[k] - analytic[k]
            k_rms[k] = float(np.sqrt(np.nanmean(d ** 2))) if np.isfinite(d).any() else float("nan")
    return DemoReport(str(session.path), labels, F, float(markers["frame_period"]), time, measured, true_pos, rms,
                      have.sum(axis=0).astype(np.int64), systematic, correct, int(decided.sum()), visible,
                      cal.get("rms", float("nan")), cal.get("points", 0), cal.get("model", ""), normal, angle,
                      kin, analytic, k_rms)


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
        "  kinematics, RMS of measured - analytic:",
    ]
    for k, unit in (("theta_dot", "rad/s"), ("phi_dot", "rad/s"), ("theta_ddot", "rad/s²"), ("phi_ddot", "rad/s²")):
        if k in r.kinematic_rms:
            scale = float(np.sqrt(np.nanmean(r.analytic[k] ** 2)))
            lines.append(f"    {k:<11} {r.kinematic_rms[k]:.4f} {unit:<7} (analytic RMS {scale:.4f})")
    lines.append("  figures:")
    lines += [f"    {p}" for p in r.figures]
    return "\n".join(lines)


def write_figures(r: DemoReport, folder: str | Path) -> list[str]:
    """``trajectories.png`` (measured vs true X, Y, Z per marker) and ``angular.png`` (angular
    velocity and acceleration, measured vs analytic) in ``folder``; returns their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    t = r.time
    fig, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    for a, axis in enumerate("XYZ"):
        for m, label in enumerate(r.labels):
            line, = axes[a].plot(t, r.truth[:, m, a], "-", lw=1.2, label=f"{label} true")
            axes[a].plot(t, r.measured[:, m, a], "o", ms=3.5, color=line.get_color(), label=f"{label} measured")
        axes[a].set_ylabel(f"{axis} (mm)")
        axes[a].grid(alpha=0.3)
    axes[0].legend(ncol=2, fontsize=8)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("RSSR spherical joints: measured (mirror method) vs true")
    fig.tight_layout()
    p1 = out / "trajectories.png"
    fig.savefig(p1, dpi=110)
    plt.close(fig)

    fig, axes = plt.subplots(2, 2, figsize=(10, 6.5), sharex=True)
    panels = (("theta_dot", "input angular velocity (rad/s)"), ("phi_dot", "output angular velocity (rad/s)"),
              ("theta_ddot", "input angular acceleration (rad/s²)"),
              ("phi_ddot", "output angular acceleration (rad/s²)"))
    for ax, (k, title) in zip(axes.ravel(), panels, strict=True):
        if k in r.analytic:
            ax.plot(t, r.analytic[k], "-", color="k", lw=1.2, label="analytic")
        if k in r.kinematics:
            ax.plot(t, r.kinematics[k], "o", ms=3.5, label="measured")
        model = "model_" + k
        if model in r.kinematics:
            ax.plot(t, r.kinematics[model], "--", lw=1.0, label="model at measured θ")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    for ax in axes[1]:
        ax.set_xlabel("time (s)")
    fig.tight_layout()
    p2 = out / "angular.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    return [str(p1), str(p2)]
