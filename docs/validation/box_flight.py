"""The thesis's thrown box (kinematics.md §5, Fig. 3.30) simulated end to end; prints a report.

Run: ``python docs/validation/box_flight.py`` (about 25 s). Writes
``docs/validation/out/box_flight_apex.png``. The tests in ``tests/plugins/kinematics/experiments`` assert
bounds on the same quantities.

Chain: vertex images directly and in the 2 m x 2 m mirror at 42 frames/s (visibility from the box
itself and from the finite mirror), Gaussian digitising noise, mirror triangulation of the
vertices seen in both views, Kabsch fit of the known box, omega from a spline of the rotations,
H_G (3.48). The noise: 0.003 mm on the 16 mm film (Table 3.1's film perturbation, ~1 count of the
0.05 mm digitiser on a ~17x enlargement) = 0.30 px at 100 px/mm.
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mirrorlab.instruments.virtual_lab.box_flight import THESIS_FILM_SIGMA_MM, thesis_box_lab  # noqa: E402
from scipy.stats import spearmanr  # noqa: E402

# the measurement chain joins the virtual lab and the plugins it validates: it lives with its tests
sys.path.insert(0, str(Path(__file__).resolve().parents[2]))
from tests.plugins.kinematics.experiments.box_flight import BoxFlight, simulate_box_flight  # noqa: E402

OUT = Path(__file__).resolve().parent / "out"
PX_PER_MM = 100.0
NOISE_PX = THESIS_FILM_SIGMA_MM * PX_PER_MM
SEEDS = range(20)
MIRROR_TOP = 2000.0


def rms(values: list[np.ndarray]) -> np.ndarray:
    return np.sqrt(np.mean(np.square(values), axis=0))


def noiseless() -> None:
    print("\n== Noiseless vertices through visibility + mirror triangulation ==")
    for rate in (200.0, 42.0):
        f = simulate_box_flight(rate=rate, method="smoothing_spline", lam=0.0)
        used = np.isfinite(f.markers).all(-1)
        trim = 10 if rate == 200 else 3
        print(f"   {rate:4.0f} frames/s  vertices in both views {f.n_both.min()}-{f.n_both.max()}  "
              f"vertex error {np.abs(f.markers[used] - f.truth.positions[used]).max():.1e} mm  "
              f"|H| variation all frames {f.variation():.2e}, {trim} end frames cut {f.variation(trim):.2e}")


def noisy(label: str, mirror_height: float, methods: tuple) -> dict[str, list[BoxFlight]]:
    lab = thesis_box_lab(mirror_height=mirror_height)
    out = {}
    for name, meth, kw in methods:
        fl = [simulate_box_flight(lab, rate=42.0, noise_px=NOISE_PX, seed=s, method=meth, **kw) for s in SEEDS]
        v = np.array([f.variation(trim=3) for f in fl])
        cv = np.median([np.nanstd(f.H_norm[3:-3]) / np.nanmean(f.H_norm[3:-3]) for f in fl])
        print(f"   {label:22s} {name:24s} |H| variation (max-min)/mean median {np.median(v):.3f} "
              f"[{v.min():.3f}-{v.max():.3f}]  std/mean {cv:.4f}")
        out[name] = fl
    return out


def apex_table(label: str, fl: list[BoxFlight]) -> dict[str, np.ndarray]:
    f0 = fl[0]
    err, rot = rms([f.H_error for f in fl]), rms([f.rotation_error for f in fl])
    phases = [("rising, below mirror top", (f0.height <= MIRROR_TOP) & (f0.t < 0.5)),
              ("near apex (above top)", f0.height > MIRROR_TOP),
              ("falling, below top", (f0.height <= MIRROR_TOP) & (f0.t > 0.5))]
    print(f"\n   {label}: per phase (RMS over {len(fl)} noise seeds; 3 end frames excluded)")
    print("   phase                       frames  height mm   n_both  sens mrad/mm  rot err mrad  |H-H0|/|H0|")
    inner = np.zeros(f0.t.size, bool)
    inner[3:-3] = True
    for name, sel in phases:
        s = sel & inner
        print(f"   {name:27s} {s.sum():5d}  {f0.height[s].min():5.0f}-{f0.height[s].max():4.0f}  "
              f"{f0.n_both[s].mean():6.2f}  {1e3 * f0.sensitivity[s].mean():10.2f}  {1e3 * np.median(rot[s]):10.2f}"
              f"  {np.median(err[s]):11.4f}")
    r1 = spearmanr(err[inner], f0.sensitivity[inner])[0]
    r2 = spearmanr(err[inner], f0.n_both[inner])[0]
    r3 = spearmanr(rot, f0.sensitivity)[0]
    print(f"   Spearman: H error vs fit sensitivity {r1:+.2f}, vs n_both {r2:+.2f}; "
          f"rotation error vs sensitivity {r3:+.2f}")
    return {"err": err, "rot": rot}


def figure(thesis: list[BoxFlight], tall: list[BoxFlight], et: dict, ec: dict) -> Path:
    f0, c0 = thesis[0], tall[0]
    t = f0.t
    fig, ax = plt.subplots(3, 1, figsize=(8, 10), sharex=False)
    a = ax[0]
    a.plot(t, f0.height, "k-", label="box centre height")
    a.axhline(MIRROR_TOP, color="k", ls=":", label="top of the 2 m mirror")
    a.set_ylabel("height (mm)")
    b = a.twinx()
    b.step(t, f0.n_both, "C3", where="mid", label="vertices in both views (2 m mirror)")
    b.step(t, c0.n_both, "C0", where="mid", alpha=0.6, label="same, 4 m mirror")
    b.set_ylabel("vertices seen directly and in the mirror")
    b.set_ylim(0, 8)
    a.legend(loc="lower left", fontsize=8)
    b.legend(loc="lower right", fontsize=8)
    a.set_title("Thrown box, 42 frames/s, 0.30 px (1.2 mm) digitising noise")
    a = ax[1]
    for f in thesis:
        a.plot(t, f.H_norm / np.linalg.norm(f.H_true), color="C3", lw=0.5, alpha=0.35)
    a.plot(t, 1 + et["err"], "C3", lw=2, label="2 m mirror: RMS |H-H0|/|H0| (20 seeds), offset by 1")
    a.plot(t, 1 + ec["err"], "C0", lw=2, label="4 m mirror (control)")
    a.axhline(1.0, color="k", lw=0.5)
    apex = f0.height > MIRROR_TOP
    a.axvspan(t[apex].min(), t[apex].max(), color="0.9", zorder=0)
    a.set_xlabel("time (s)")
    a.set_ylabel("|H_G| / |H_G true|")
    a.legend(fontsize=8)
    a = ax[2]
    inner = slice(3, -3)
    a.scatter(1e3 * f0.sensitivity[inner], et["err"][inner], c=f0.n_both[inner], cmap="viridis", label="2 m mirror")
    a.scatter(1e3 * c0.sensitivity[inner], ec["err"][inner], marker="x", color="C0", label="4 m mirror")
    a.set_xlabel("rigid-fit sensitivity sqrt(tr J^-1) (mrad per mm of point noise); colour = vertices used")
    a.set_ylabel("RMS |H - H0| / |H0| per frame")
    a.legend(fontsize=8)
    fig.tight_layout()
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "box_flight_apex.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main() -> None:
    lab = thesis_box_lab()
    sc = lab.scene
    print("== Thrown box (200x200x300 mm, 2.2 kg, body rate (3,1,6) rad/s), one camera + vertical mirror ==")
    print(f"   release centre {sc.centre0} mm, velocity {sc.velocity0} mm/s, flight {sc.duration} s, "
          f"apex {sc.centre0[1] + sc.velocity0[1] ** 2 / (2 * sc.gravity):.0f} mm; mirror 2 m x 2 m on the floor")
    f = simulate_box_flight(rate=42.0, noise_px=NOISE_PX)
    print(f"   16 mm cine frame, 10 mm lens, {PX_PER_MM:.0f} px/mm; noise {THESIS_FILM_SIGMA_MM} mm on film = "
          f"{NOISE_PX:.2f} px = {f.noise_object_mm:.2f} mm at the box")
    noiseless()
    print("\n== 42 frames/s with digitising noise (20 seeds; 3 end frames cut) ==")
    methods = (("GCV smoothing spline", "smoothing_spline", {}),
               ("thesis filter + spline", "thesis_spline", {}))
    th = noisy("2 m mirror (thesis)", 2000.0, methods)
    ct = noisy("4 m mirror (control)", 4000.0, methods[:1])
    et = apex_table("2 m mirror, GCV", th["GCV smoothing spline"])
    apex_table("2 m mirror, thesis filter + spline", th["thesis filter + spline"])
    ec = apex_table("4 m mirror (control), GCV", ct["GCV smoothing spline"])
    print(f"\nfigure written to {figure(th['GCV smoothing spline'], ct['GCV smoothing spline'], et, ec)}")


if __name__ == "__main__":
    main()
