"""The thesis's thrown box filmed with a mirror, end to end (issue 5, kinematics.md §5, Fig. 3.30).

Image positions with visibility -> mirror triangulation -> rigid fit of the box -> omega -> H_G.
Figures printed by ``docs/validation/box_flight.py``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.instruments.virtual_lab import make_lab
from mirrorlab.instruments.virtual_lab.box_flight import THESIS_FILM_SIGMA_MM, thesis_box_lab
from mirrorlab.plugins.kinematics import kabsch
from mirrorlab.plugins.kinematics.synthetic import box_inertia, box_vertices
from mirrorlab.plugins.photogrammetry import PinholeCamera
from mirrorlab.plugins.photogrammetry.mirror import triangulate_mirror
from scipy.spatial.transform import Rotation
from scipy.stats import spearmanr

from tests.derived_bounds import natural_end_error
from tests.plugins.kinematics.experiments.box_flight import rotation_sensitivity, simulate_box_flight
from tests.tolerances import roundoff

VERTS = box_vertices([200.0, 200.0, 300.0])
NOISE_PX = THESIS_FILM_SIGMA_MM * 100.0          # 0.003 mm on film at 100 px/mm


@pytest.fixture(scope="module")
def noisy_flights():
    lab = thesis_box_lab()
    return [simulate_box_flight(lab, rate=42.0, noise_px=NOISE_PX, seed=s) for s in range(6)]


def test_noiseless_200fps_through_visibility_and_mirror_keeps_H_constant():
    f = simulate_box_flight(rate=200.0, method="smoothing_spline", lam=0.0)
    used = np.isfinite(f.markers).all(-1)
    # vertices exact where seen in both views (rounding of the ray intersection: distances along the
    # rays up to a, amplified by 1 / sin of the rays' angle); visibility really limits the fit
    lab = thesis_box_lab()
    c, mirror = lab.camera, lab.mirrors[0]
    cam = PinholeCamera(c.K, c.dist, c.R, c.t, c.image_size)  # the plugin's model of the lab's camera
    tri = triangulate_mirror(cam.camera_center, mirror.centre, mirror.normal, cam.rays(f.truth.real_xy[used]),
                             cam.rays(f.truth.virtual_xy[:, 0][used]), on_degenerate="flag")
    tol = roundoff(cond=1 / np.sin(tri.angle).min(), scale=max(tri.a1.max(), tri.a2.max()), ops=20)
    assert np.abs(f.markers[used] - f.truth.positions[used]).max() <= tol
    assert f.n_both.min() == 3 and f.n_both.max() == 6
    assert np.isfinite(f.H).all()
    # method: the interpolating spline's omega error, relative, per frame: the natural end condition's
    # (|R''| <= |w|² + |w'|, tests/derived_bounds.py) plus the superconvergent interior term; x2 for
    # vee(R' Rᵀ), x I_max / I_min from omega to H. |H| varies by at most twice the largest relative
    # error of H: the ends dominate the untrimmed figure; 10 frames = 0.05 s cut leaves 0.27^10 of them
    w = f.truth.analytic["omega_world"]
    w_norm = np.linalg.norm(w, axis=1)
    curvature = (w_norm**2).max() + np.linalg.norm(np.gradient(w, f.t, axis=0), axis=1).max()
    h = 1 / 200.0
    from_end = np.minimum(np.arange(f.t.size), f.t.size - 1 - np.arange(f.t.size))
    inertia = box_inertia(2.2, [0.2, 0.2, 0.3])
    rel = inertia.max() / inertia.min() * (2 * natural_end_error(h, curvature, from_end)
                                           + 2 * (w_norm.max() * h) ** 4 / 180 * w_norm.max()) / w_norm.min()
    assert f.variation() <= 2 * rel.max() / (1 - rel.max())
    inner = rel[10:-10].max()
    assert f.variation(trim=10) <= 2 * inner / (1 - inner)
    assert np.max(f.H_error[10:-10]) <= inner


def test_42fps_with_digitising_noise_variation_is_finite_and_reported(noisy_flights):
    v = np.array([f.variation(trim=3) for f in noisy_flights])
    print(f"|H_G| variation at 42 frames/s, sigma = {NOISE_PX:.2f} px "
          f"({noisy_flights[0].noise_object_mm:.2f} mm): median {np.median(v):.3g}, range {v.min():.3g}-{v.max():.3g}")
    assert np.isfinite(v).all()
    # a wide bracket around the thesis's order of magnitude (Fig. 3.30): noise of ~1 mm on the box,
    # differentiated at 42 frames/s, makes |H_G| vary by percents; a statistical figure over 6 seeds
    assert 1e-3 < np.median(v) < 0.2
    # 0.3 px · mean distance / f (1000 px): the lab's 3.9 m gives 1.17 mm; the bracket is 2.7-5.3 m
    assert 0.8 < noisy_flights[0].noise_object_mm < 1.6


def test_error_grows_near_apex_with_the_visibility_loss(noisy_flights):
    f0 = noisy_flights[0]
    err = np.sqrt(np.mean([f.H_error ** 2 for f in noisy_flights], axis=0))
    rot = np.sqrt(np.mean([f.rotation_error ** 2 for f in noisy_flights], axis=0))
    inner = slice(3, -3)
    rho_h = spearmanr(err[inner], f0.sensitivity[inner])[0]
    rho_n = spearmanr(err[inner], f0.n_both[inner])[0]
    rho_r = spearmanr(rot, f0.sensitivity)[0]
    # statistical: rank correlations over ~40 frames of 6 noisy flights (0 under independence, with a
    # standard error of ~1/sqrt(40) = 0.16: the thresholds are >= 2.5 of them)
    assert rho_h > 0.5 and rho_n < -0.5 and rho_r > 0.4, (rho_h, rho_n, rho_r)
    apex = f0.height > 2000.0                        # box centre above the mirror's top edge
    assert 10 <= apex.sum() <= 25
    assert f0.n_both[apex].mean() < 4.5 < f0.n_both[~apex].mean()
    rest = ~apex
    rest[:3] = rest[-3:] = False
    # statistical: the apex frames (fewer vertices seen) err more; 15 % is the margin of the claim
    assert np.median(err[apex]) > 1.15 * np.median(err[rest])
    assert np.median(rot[apex]) > 1.15 * np.median(rot[rest])


def test_taller_mirror_removes_the_apex_visibility_loss():
    f = simulate_box_flight(thesis_box_lab(mirror_height=4000.0), rate=42.0)
    apex = f.height > 2000.0
    assert f.n_both[apex].mean() > 5.0


def test_sensitivity_predicts_monte_carlo_rotation_error():
    rng = np.random.default_rng(3)
    for mask in ([True] * 8, [True, True, True, True, False, False, False, False], [1, 1, 0, 1, 0, 0, 0, 0]):
        used = np.asarray(mask, bool)
        pts = np.where(used[:, None], VERTS, np.nan)
        sigma = 1.0
        noisy = pts[None] + rng.normal(0.0, sigma, (4000, 8, 3))
        R, _, _, _ = kabsch(VERTS, noisy)
        ang = np.linalg.norm(Rotation.from_matrix(R).as_rotvec(), axis=1)
        predicted = sigma * rotation_sensitivity(VERTS, used[None])[0]
        # Monte Carlo: the RMS of N = 4000 draws of a weighted chi-square (3 dof, Var/E² <= 2) has a
        # relative standard error <= sqrt(2 / N) / 2 = 1.1 %, so 6 % is > 5 standard errors; the
        # linearisation's bias is O((sigma / 100 mm)²) = 1e-4
        assert np.sqrt(np.mean(ang ** 2)) == pytest.approx(predicted, rel=0.06)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.booleans(), min_size=8, max_size=8), st.integers(0, 7), st.integers(0, 2**31 - 1))
def test_sensitivity_rotation_invariant_and_monotone(mask, extra, seed):
    used = np.asarray(mask, bool)
    more = used.copy()
    more[extra] = True
    Q = Rotation.random(random_state=seed).as_matrix()
    s, s_more = rotation_sensitivity(VERTS, np.stack([used, more]))
    s_rot = rotation_sensitivity(VERTS @ Q.T, used[None])[0]
    # sqrt(trace(J⁻¹)) from eigenvalues of J: relative rounding eps · ev_max / ev_min of J
    tol = roundoff(cond=_second_moment_cond(VERTS, used), ops=10)
    assert s_more <= s * (1 + tol) or np.isinf(s)
    assert (np.isinf(s) and np.isinf(s_rot)) or s_rot == pytest.approx(s, rel=tol)
    assert np.isinf(s) == (used.sum() < 3)


def _second_moment_cond(reference: np.ndarray, used: np.ndarray) -> float:
    """ev_max / ev_min of J = Σ |d|² E - d dᵀ over the used points (1 when fewer than 3)."""
    if used.sum() < 3:
        return 1.0
    d = reference[used] - reference[used].mean(axis=0)
    ev = np.linalg.eigvalsh((d**2).sum() * np.eye(3) - d.T @ d)
    return float(ev[-1] / ev[0])


def test_wrong_lab_is_refused():

    with pytest.raises(ValueError, match="BoxScene"):
        simulate_box_flight(make_lab("rssr"))
    with pytest.raises(ValueError, match="noise_px"):
        simulate_box_flight(noise_px=-1.0)


def test_docstring_examples_run():
    import doctest

    import mirrorlab.instruments.virtual_lab.box_flight as lab

    from tests.plugins.kinematics.experiments import box_flight as chain

    results = [doctest.testmod(module, optionflags=doctest.NORMALIZE_WHITESPACE) for module in (lab, chain)]
    assert sum(r.attempted for r in results) >= 5 and not any(r.failed for r in results)
