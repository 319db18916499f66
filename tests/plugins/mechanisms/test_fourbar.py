"""Planar four-bar reconstruction from unlabeled markers against the virtual lab's four-bar (§4)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from mirrorlab.instruments.virtual_lab.scenes import FourBarScene
from mirrorlab.plugins.mechanisms import (
    DegenerateGeometry,
    GroupingError,
    InvalidPoints,
    reconstruct_four_bar,
)
from mirrorlab.plugins.mechanisms.synthetic import TABLE_5_1, THESIS_FOUR_BAR, four_bar_markers, four_bar_positions

from tests.derived_bounds import perturbation_rounding
from tests.tolerances import abs_err, roundoff


def _rounding_bounds(points: np.ndarray, method: str = "least_squares", **kw: object) -> tuple[float, float]:
    """Rounding bounds (mm) on the link lengths and on the joints reconstructed from exact markers,
    from the reconstruction's measured sensitivity (tests/derived_bounds.py); an exact initial
    estimate is refined by least squares to residuals at that same level, so this covers both methods."""
    def outputs(p: np.ndarray) -> np.ndarray:
        fb = reconstruct_four_bar(p, method, **kw)
        return np.concatenate([list(fb.lengths.values()), fb.joints.ravel()])

    bound = perturbation_rounding(outputs, points)
    return float(bound[:4].max()), float(bound[4:].max())


def _true_joints(frames: int, theta0: float = 0.0) -> np.ndarray:
    scene = FourBarScene(theta0=theta0)
    a = scene.state(np.arange(frames) * np.deg2rad(12.0) / scene.omega).analytic
    return np.stack([a["G1"], a["J1"], a["J2"], a["G2"]], 1)[..., :2]


def test_the_synthetic_four_bar_is_the_virtual_lab_scene() -> None:
    """The plugin's own generator (loop closed by the cosine law, complex numbers) against the virtual
    lab's scene (circle intersection): the same mechanism and markers, independently computed."""
    scene = FourBarScene()
    theta = np.linspace(-7.0, 7.0, 701)
    expected = scene.positions(theta / scene.omega)[..., :2]
    # J2 where the circles meet: the root's condition is coupler / h, h the height of J2 over the
    # line J1-G2 (it vanishes when the links line up); ~10 roundings of coordinates up to the reach
    a = scene.state(theta / scene.omega).analytic
    J21, G21 = a["J2"] - a["J1"], a["G2"] - a["J1"]
    h = np.abs(np.cross(J21, G21)[:, 2]) / np.linalg.norm(G21, axis=1)
    tol = roundoff(cond=float(np.max(scene.coupler / h)), scale=np.abs(expected).max(), ops=20)
    assert abs_err(four_bar_positions(theta), expected) <= tol
    _, truth = four_bar_markers(30, noise="none", shuffle=False, theta0=0.7)
    assert abs_err(truth, scene.positions((0.7 + np.arange(30) * np.deg2rad(12.0)) / scene.omega)[..., :2]) <= tol


@pytest.mark.parametrize("method", ["least_squares", "thesis"])
@pytest.mark.parametrize("theta0", [0.0, 0.7])
def test_noiseless_shuffled_is_exact(method: str, theta0: float) -> None:
    points, _ = four_bar_markers(30, noise="none", theta0=theta0, seed=1)
    fb = reconstruct_four_bar(points, method)
    tol_lengths, tol_joints = _rounding_bounds(points, method)
    for k, v in THESIS_FOUR_BAR.items():
        assert fb.lengths[k] == pytest.approx(v, abs=tol_lengths), k
    truth = _true_joints(30, theta0)                     # the scene's own rounding on top
    np.testing.assert_allclose(fb.joints, truth, rtol=0, atol=tol_joints + roundoff(scale=np.abs(truth).max(), ops=10))
    np.testing.assert_allclose(fb.ground_pivots, [[0.0, 0.0], [230.0, 0.0]], rtol=0, atol=tol_joints)
    # the model reproduces exact markers: residuals at the markers' rounding
    assert fb.rms <= roundoff(scale=float(np.abs(points).max()), ops=10)
    assert fb.joints.shape == (30, 4, 2) and fb.residuals.shape == (30, 9)


def test_noiseless_with_gaps_least_squares() -> None:
    points, _ = four_bar_markers(30, noise="none", missing=0.1, seed=2)
    fb = reconstruct_four_bar(points)
    assert max(abs(fb.lengths[k] - v) for k, v in THESIS_FOUR_BAR.items()) <= _rounding_bounds(points)[0]
    assert np.isnan(fb.residuals).sum() > 0                     # missing samples stay NaN


def test_thesis_digitising_noise_against_table_5_1(capsys: pytest.CaptureFixture[str]) -> None:
    """LS within 1 % on all four links, 20 shuffled noisy runs; thesis errors printed next to Table 5.1."""
    ls, th = [], []
    for seed in range(20):
        points, _ = four_bar_markers(30, noise="uniform", seed=seed)
        ls.append(reconstruct_four_bar(points).errors(THESIS_FOUR_BAR))
        th.append(reconstruct_four_bar(points, "thesis").errors(THESIS_FOUR_BAR))
    worst = {k: max(abs(e[k]) for e in ls) for k in THESIS_FOUR_BAR}
    # the acceptance figure of the least-squares method on the thesis's digitising noise (±0.56 and
    # ±1.26 mm uniform over 30 frames); a statistical figure (max over 20 seeds), not rounding
    assert max(worst.values()) < 0.01, worst
    with capsys.disabled():
        print("\nlink     Table 5.1 %   LS max |err| %   thesis median |err| %   thesis max |err| %")
        for k in THESIS_FOUR_BAR:
            t = [abs(e[k]) * 100 for e in th]
            print(f"{k:8s} {TABLE_5_1[k][1]:+10.1f} {100 * worst[k]:15.2f} {np.median(t):20.2f} {max(t):19.2f}")


def test_gaussian_one_unit_noise_least_squares_median() -> None:
    """The harsher reading (1 and 2 digitiser units RMS): medians within 2 % (measured: output link 1.1 %)."""
    errs = [reconstruct_four_bar(four_bar_markers(30, noise="gaussian", seed=s)[0]).errors(THESIS_FOUR_BAR)
            for s in range(10)]
    med = {k: float(np.median([abs(e[k]) for e in errs])) for k in THESIS_FOUR_BAR}
    # statistical acceptance figure (median over 10 seeds of the harsher noise reading); the bound is
    # not derived from first principles (error propagation through grouping, circle fits and the
    # model fit), it rests on the spec's 2 %
    assert max(med.values()) < 0.02, med


def test_residuals_measure_the_noise() -> None:
    points, _ = four_bar_markers(30, noise="uniform", seed=7, shuffle=False)
    fb = reconstruct_four_bar(points)
    # uniform errors of +-0.5625 and +-1.256 mm: RMS sqrt((0.5625^2 + 1.256^2) / 3) = 0.79 mm per marker,
    # less the fitted parameters' share (55 of ~420 coordinates: x0.93); over ~200 markers the RMS has
    # a ~5 % standard error, so the bracket is > 4 standard errors wide on each side
    assert 0.5 < fb.rms < 1.0
    assert np.isnan(fb.residuals[:, list(fb.links["ground"])]).all()


def test_refine_off_and_registration_off_still_work() -> None:
    points, _ = four_bar_markers(30, noise="none", seed=8)
    a = reconstruct_four_bar(points, refine=False)
    b = reconstruct_four_bar(points, register=False)
    tol_a, tol_b = _rounding_bounds(points, refine=False)[0], _rounding_bounds(points, register=False)[0]
    for k, v in THESIS_FOUR_BAR.items():
        assert a.lengths[k] == pytest.approx(v, abs=tol_a) and b.lengths[k] == pytest.approx(v, abs=tol_b)


def test_film_drift_is_removed_by_registration() -> None:
    points, _ = four_bar_markers(30, noise="none", shuffle=False, seed=9)
    rng = np.random.default_rng(0)
    ang = rng.normal(scale=0.01, size=30)
    c, s = np.cos(ang), np.sin(ang)
    R = np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)
    drifted = np.einsum("tij,tmj->tmi", R, points) + rng.normal(scale=3.0, size=(30, 1, 2))
    fb = reconstruct_four_bar(drifted)
    assert max(abs(fb.lengths[k] - v) for k, v in THESIS_FOUR_BAR.items()) <= _rounding_bounds(drifted)[0]


def test_bad_input_errors() -> None:
    with pytest.raises(InvalidPoints, match=r"\(T, M, 2\)"):
        reconstruct_four_bar(np.zeros((30, 9, 3)))
    with pytest.raises(InvalidPoints, match="at least 3 frames"):
        reconstruct_four_bar(np.zeros((2, 9, 2)))
    with pytest.raises(InvalidPoints, match="unknown method"):
        reconstruct_four_bar(np.zeros((5, 9, 2)), "magic")
    gaps, _ = four_bar_markers(30, noise="none", missing=0.1, seed=2)
    with pytest.raises(InvalidPoints, match="every marker in every frame"):
        reconstruct_four_bar(gaps, "thesis")
    short, _ = four_bar_markers(20, noise="none", seed=2)
    with pytest.raises(InvalidPoints, match="needs 30 frames, got 20"):
        reconstruct_four_bar(short, "thesis")
    points, _ = four_bar_markers(30, noise="none", shuffle=False, seed=2)
    with pytest.raises(GroupingError, match="expected 3 separate moving bodies"):
        reconstruct_four_bar(points[:, :7])
    still = np.broadcast_to(points[:1], (5, 9, 2)) + np.arange(5)[:, None, None] * 1e-3
    with pytest.raises((GroupingError, DegenerateGeometry)):
        reconstruct_four_bar(still)


@settings(max_examples=10, deadline=None)
@given(st.floats(-np.pi, np.pi), st.floats(-1000, 1000), st.floats(-1000, 1000), st.booleans(), st.integers(0, 50))
def test_lengths_invariant_under_rigid_motion_and_mirroring(angle: float, dx: float, dy: float, mirror: bool,
                                                            seed: int) -> None:
    points, _ = four_bar_markers(30, noise="none", seed=seed)
    c, s = np.cos(angle), np.sin(angle)
    R = np.array([[c, -s], [s, c]]) @ (np.diag([1.0, -1.0]) if mirror else np.eye(2))
    for method in ("least_squares", "thesis"):
        moved = points @ R.T + [dx, dy]
        fb = reconstruct_four_bar(moved, method)
        tol = _rounding_bounds(moved, method)[0]         # coordinates up to ~1.3 m round coarser
        for k, v in THESIS_FOUR_BAR.items():
            assert fb.lengths[k] == pytest.approx(v, abs=tol), (method, k)

