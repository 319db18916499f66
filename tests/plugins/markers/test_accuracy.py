"""Detection accuracy against rendered ground truth (issue [demo] acceptance, spec analysis.md §1)."""

from __future__ import annotations

import numpy as np
import pytest
from mirrorlab.plugins.markers import detect_markers

from tests.tolerances import roundoff

from .render import binary_disc_frame, random_centers, render_markers

RADII = (3.0, 5.0, 10.0, 20.0)
BLURS = (0.5, 1.0, 2.0)


def _matched_errors(found: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Errors (K, 2) of the detection nearest to each true centre; every marker must be found once."""
    d = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=2)
    assert len(found) == len(truth), (len(found), len(truth))
    j = np.argmin(d, axis=0)
    assert len(set(j.tolist())) == len(truth)
    return found[j] - truth


def _scene(radius: float, blur: float, seed: int):
    rng = np.random.default_rng(seed)
    shape = (int(18 * radius + 120), int(24 * radius + 160))
    centres = random_centers(rng, shape, 12, radius)
    return render_markers(shape, centres, radius, blur=blur, noise=2.0, rng=rng), centres


def rms(e: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum(e ** 2, axis=1))))


@pytest.mark.parametrize("radius", RADII)
@pytest.mark.parametrize("blur", BLURS)
def test_subpixel_rms_within_five_hundredths_of_a_pixel(radius: float, blur: float) -> None:
    """Radius 3–20 px, blur σ 0.5–2 px, noise σ 2 grey levels: ≤ 0.05 px RMS (uint8 images).

    0.05 px is the acceptance figure of the demo issue (method error: sampling, uint8 levels, noise).
    """
    image, truth = _scene(radius, blur, seed=int(radius * 10 + blur * 100))
    sub = rms(_matched_errors(detect_markers(image).xy, truth))
    ell = rms(_matched_errors(detect_markers(image, ellipse=True).xy, truth))
    assert sub <= 0.05, sub
    assert ell <= 0.05, ell
    if 2 * radius <= 20:  # the thesis detector handles markers up to 24 px only
        thesis = rms(_matched_errors(detect_markers(image, method="thesis").xy, truth))
        # integer output: sqrt(2 / 12) = 0.41 px (2-D) from quantisation alone; an RMS of 12 markers
        # (24 coordinates) is good to ~15 %: 0.2-0.6 is wider than +-3 sd
        assert 0.2 < thesis < 0.6, thesis
        assert thesis > 5 * sub


def test_oblique_markers_centres_axes_and_angle() -> None:
    rng = np.random.default_rng(7)
    shape = (300, 400)
    truth = random_centers(rng, shape, 10, 12.0, spacing=40)
    angles = rng.uniform(0, 180, len(truth))
    image = render_markers(shape, truth, 12.0, axes_ratio=0.5, angle_deg=angles, blur=1.0, noise=2.0, rng=rng)
    for ellipse in (False, True):
        det = detect_markers(image, ellipse=ellipse)
        e = _matched_errors(det.xy, truth)
        assert rms(e) <= 0.05  # the acceptance figure, as above
        order = np.argmin(np.linalg.norm(det.xy[:, None] - truth[None], axis=2), axis=0)
        # blur sigma = 1 px adds sigma^2 to both second moments (semi-axes 12, 6: a^2 / 4 = 36, 9):
        # e = sqrt(1 - 10 / 37) = 0.854, 0.012 below 0.866; 0.03 adds pixel sampling and noise
        np.testing.assert_allclose(det.eccentricity[order], np.sqrt(1 - 0.5 ** 2), atol=0.03)
        # orientation of a 2:1 ellipse from its moments, under 2 grey levels of noise on ~220: a few
        # tenths of a degree; 2 deg
        dang = np.angle(np.exp(2j * (det.angle[order] - np.deg2rad(angles)))) / 2
        assert np.max(np.abs(dang)) < np.deg2rad(2.0)
        if ellipse:  # the fitted half-contrast ellipse has the drawn axes (blur shrinks it slightly)
            # blur moves the half-contrast line of an edge of curvature radius R inward by ~sigma^2 / (2 R):
            # 0.17 px at the major-axis ends (R = b^2 / a = 3 px); 0.35 px with the contour's sampling
            np.testing.assert_allclose(det.axes[order], [[12.0, 6.0]] * len(truth), atol=0.35)


def test_binary_scanner_frames_pixel_centroid_is_exact() -> None:
    """512 × 344 binary frames: the centre is the exact pixel centroid (to rounding) of each disc."""
    rng = np.random.default_rng(3)
    truth = random_centers(rng, (344, 512), 12, 6.0, spacing=40)
    frame = binary_disc_frame((344, 512), truth, 6.0)
    det = detect_markers(frame)
    yy, xx = np.mgrid[0:344, 0:512]
    exact = []
    for c in truth:
        inside = ((xx - c[0]) ** 2 + (yy - c[1]) ** 2 <= 36.0)
        exact.append([xx[inside].mean(), yy[inside].mean()])
    # both are means of the same integer coordinates (~113 per disc): the divisions' and sums' rounding
    np.testing.assert_allclose(_matched_errors(det.xy, np.array(exact)), 0.0, atol=roundoff(scale=512.0, ops=det.area.max()))
    np.testing.assert_array_equal(det.contrast, 255.0)
    # pixel-centre sampling of a 12 px disc: analysis.md §1.2 gives 0.04-0.08 px RMS for 10-16 px binary
    # discs; 0.12 is 1.5x its upper end
    assert rms(_matched_errors(det.xy, truth)) < 0.12


def test_thesis_on_binary_discs_matches_the_spec_statistics() -> None:
    """Spec §1.1 check: 10 and 16 px discs, random centres: unbiased within 0.09 px, RMS 0.30–0.34 per axis."""
    rng = np.random.default_rng(11)
    for diameter in (10.0, 16.0):
        errors = []
        for _ in range(13):  # 13 frames × 12 discs ≈ 150 trials
            truth = random_centers(rng, (344, 512), 12, diameter / 2, spacing=45, margin=20)
            det = detect_markers(binary_disc_frame((344, 512), truth, diameter / 2), method="thesis")
            errors.append(_matched_errors(det.xy, truth))
        e = np.concatenate(errors)
        # analysis.md §1.1: unbiased within 0.09 px, 0.30-0.34 px RMS per axis over 150 trials; an RMS of
        # ~156 samples is good to 1 / sqrt(2 * 156) = 6 %, so 0.25-0.40 is the spec's range +- 2.5 sd
        assert np.all(np.abs(e.mean(axis=0)) < 0.09), e.mean(axis=0)
        per_axis = np.sqrt(np.mean(e ** 2, axis=0))
        assert np.all((per_axis > 0.25) & (per_axis < 0.40)), per_axis
        assert np.all(np.mod(det.xy, 1.0) == 0.5)  # integer window positions + 0.5
