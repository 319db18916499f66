"""Validation figures of mirrorlab.plugins.kinematics (prints a report; no assertions).

Run: ``python docs/validation/kinematics_checks.py``. The tests in ``tests/plugins/kinematics`` assert
bounds on the same quantities; this script prints the measured values.
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import mirrorlab.plugins.kinematics as K
import numpy as np
from mirrorlab.plugins.kinematics.rssr import THESIS_THETA_DOT
from mirrorlab.plugins.kinematics.synthetic import (
    box_inertia,
    box_vertices,
    derivative_errors,
    tumbling_box_markers,
)

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"
G = 9806.65
I_BOX = box_inertia(2.2, [0.2, 0.2, 0.3])
METHODS = [
    ("thesis (filter+spline)", "thesis_spline", {}),
    ("thesis spline, no filter", "thesis_spline", {"prefilter": False}),
    ("smoothing spline (GCV)", "smoothing_spline", {}),
    ("interp. spline (lam=0)", "smoothing_spline", {"lam": 0.0}),
    ("butterworth 8 Hz", "butterworth", {"cutoff": 8.0}),
]


def filter_response() -> None:
    print("\n== 1-2-3-3-2-1 filter |H(sigma)| ==")
    for s in (0.02, 0.05, 0.10, 0.15, 0.20, 0.25, 1 / 3, 0.40, 0.50):
        print(f"  sigma={s:.4f}  |H|={abs(float(K.thesis_filter_response(s))):.4f}")


def analytic() -> None:
    print("\n== Analytic signals, 42 samples/s over 1 s, max error on [0.2, 0.8] s / amplitude ==")
    print("   (value, velocity, acceleration)")
    for noise in (0.0, 1e-3):
        print(f"  noise sd = {noise:g} (signal units)")
        for label, m, kw in METHODS:
            if noise and m == "butterworth":
                kw = {"cutoff": 8.0}
            errs = derivative_errors(m, noise=noise, **kw)
            row = "  ".join(f"{n}: " + "/".join(f"{e:.1e}" for e in v) for n, v in errs.items())
            print(f"   {label:26s} {row}")


def rssr() -> None:
    print("\n== RSSR: measured phi_dot, phi_ddot (from S_A, S_C markers) vs model (3.42-3.44) ==")
    print("   max |error| over the middle 80 % / max |model|; two crank revolutions, noiseless")
    for fps in (100.0, 3.0):
        t = np.arange(0.0, 2 * 2 * np.pi / THESIS_THETA_DOT, 1.0 / fps)
        s = K.rssr_state(THESIS_THETA_DOT * t)
        theta, phi = K.rssr_angles_from_markers(s.S_A, s.S_C)
        n = t.size
        sl = slice(n // 10, n - n // 10)
        for label, m, kw in METHODS[:4]:
            _, v, a = K.derivatives(t, phi, method=m, **kw)
            _, tv, _ = K.derivatives(t, theta, method=m, **kw)
            ev = np.nanmax(np.abs(v - s.phi_dot)[sl]) / np.abs(s.phi_dot).max()
            ea = np.nanmax(np.abs(a - s.phi_ddot)[sl]) / np.abs(s.phi_ddot).max()
            et = np.nanmax(np.abs(tv - THESIS_THETA_DOT)[sl]) / THESIS_THETA_DOT
            print(f"   {fps:5.0f} fps  {label:26s} phi_dot {ev:.2e}  phi_ddot {ea:.2e}  theta_dot {et:.2e}")


def box() -> None:
    print("\n== Torque-free box 200x200x300 mm, 2.2 kg, body rate (3,1,6) rad/s, 1 s ==")
    print("   |H_G| variation = (max-min)/mean over frames (ends excluded); std/mean in brackets")
    ref = box_vertices([200, 200, 300])
    for rate, noise in ((200.0, 0.0), (42.0, 0.0), (42.0, 0.5), (42.0, 1.0), (200.0, 0.5)):
        t, m, body = tumbling_box_markers(rate=rate, noise_mm=noise, seed=1)
        cut = 10 if rate == 200 else 3
        for label, meth, kw in METHODS[:4]:
            rb = K.rigid_body_motion(t, m, reference=ref, method=meth, **kw)
            H = K.angular_momentum(np.swapaxes(rb.R, -1, -2), I_BOX, rb.omega)
            nH = np.linalg.norm(H, axis=1)[cut:-cut]
            nH = nH[np.isfinite(nH)]
            print(f"   {rate:4.0f} fps noise {noise:.1f} mm  {label:26s} "
                  f"{np.ptp(nH) / nH.mean():.2e} ({nH.std() / nH.mean():.1e})")
        # thesis route: a, b from the rigid fit, spline derivatives, (3.51), T (3.52), (3.48)
        R, _, _, _ = K.kabsch(ref, m)
        a = R @ np.array([200.0, 0, 0]) / 1000
        b = R @ np.array([0.0, 200, 0]) / 1000
        _, c1, _ = K.derivatives(t, a, method="thesis_spline", prefilter=False)
        _, c2, _ = K.derivatives(t, b, method="thesis_spline", prefilter=False)
        om, res = K.angular_velocity_two_vectors(a, b, c1, c2, on_degenerate="nan")
        H = K.angular_momentum(K.body_frame(a, b), np.diag([I_BOX[0], I_BOX[2], I_BOX[1]]), om)[cut:-cut]
        nH = np.linalg.norm(H, axis=1)
        print(f"   {rate:4.0f} fps noise {noise:.1f} mm  {'thesis route (3.51), spline':26s} "
              f"{np.nanmax(nH) / np.nanmean(nH) - np.nanmin(nH) / np.nanmean(nH):.2e}  "
              f"component spread/|H| {np.nanmax(np.ptp(H, axis=0)) / np.nanmean(nH):.1e}  "
              f"rigidity resid max {np.nanmax(np.abs(res)):.1e}")


def ball() -> None:
    print("\n== Thrown ball, 300 Hz: median acceleration per free flight (m/s^2; trimmed 0.05 s) ==")
    d = K.read_qualisys_tsv(DATA / "trajectories" / "6_throws_minimal_tracking_loss.tsv")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        pos = np.nanmean(d.points[:, 6:], axis=1)
    flights = [(31, 377), (1036, 1348), (2243, 2508), (3169, 3411), (4632, 4872), (5731, 5944)]
    for label, m, kw in (METHODS[0], METHODS[2], ("butterworth residual", "butterworth", {})):
        t0 = time.perf_counter()
        _, _, acc = K.derivatives(d.time, pos, method=m, **kw)
        dt = time.perf_counter() - t0
        meds, pooled = [], []
        for f0, f1 in flights:
            a = acc[f0 - 1 + 15 : f1 - 15]
            a = a[np.isfinite(a).all(1)]
            meds.append(np.median(a, axis=0) / 1000)
            pooled.append(a)
        med = np.median(np.concatenate(pooled), axis=0) / 1000
        print(f"   {label:24s} pooled ({med[0]:+.3f}, {med[1]:+.3f}, {med[2]:+.3f})  "
              f"z/g-1 = {(-med[2] * 1000 / G - 1) * 100:+.1f} %  [{dt:.1f} s]")
        print("      per flight z: " + ", ".join(f"{v[2]:.3f}" for v in meds)
              + "   max |horizontal|: " + f"{np.abs(np.array(meds)[:, :2]).max():.3f}")


def elbow() -> None:
    print("\n== Elbow flexion (theta3, eq 6.7) from markers_analogs.c3d vs OpenSim inverse_kin.mot ==")
    c = K.read_c3d(DATA / "mocap" / "markers_analogs.c3d")
    m = {lab.split(":")[-1]: c.points[:, i] for i, lab in enumerate(c.labels)}
    el = 0.5 * (m["EPICl"] + m["EPICm"])
    wr = 0.5 * (m["STYLr"] + m["STYLu"])
    th3 = np.degrees(K.elbow_flexion(m["ACRO_tip"], el, wr))
    lines = (DATA / "mocap" / "inverse_kin.mot").read_text().splitlines()
    h = next(i for i, ln in enumerate(lines) if ln.startswith("endheader"))
    cols = lines[h + 1].split(",")
    rows = np.array([[float(x) for x in ln.split(",")[: len(cols)]] for ln in lines[h + 2:] if ln.strip()])
    fr = np.rint(rows[:, 0] * c.rate).astype(int) - c.first_frame
    d = th3[fr] - rows[:, cols.index("elbow_flexion")]
    ok = np.isfinite(d)
    print(f"   rows {ok.sum()}/{len(d)}  RMS {np.sqrt(np.mean(d[ok] ** 2)):.2f} deg  mean {d[ok].mean():+.2f}"
          f"  max {np.abs(d[ok]).max():.2f}  r {np.corrcoef(th3[fr][ok], rows[ok, cols.index('elbow_flexion')])[0, 1]:.4f}")


if __name__ == "__main__":
    filter_response()
    analytic()
    rssr()
    box()
    ball()
    elbow()
