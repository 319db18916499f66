"""The array acoustics against the spec's verified figures (§2.2-§2.4, §5, §6.2-§6.4, §6.7)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from mirrorlab.instruments.ultrasonic_tracker.acoustics import (
    array_directivity,
    element_directivity,
    half_angle,
    round_trip,
    steering_groups,
    wavenumber,
)

from tests.tolerances import roundoff

K = wavenumber()                       # c = 344 m/s, lambda = 8.60 mm


def test_single_element_half_angle() -> None:
    # half angles printed to 0.1 deg (instruments.md §6.7): half a unit; the root finder is far finer
    wide = math.radians(80.0)
    assert math.degrees(half_angle(lambda a: element_directivity(a, K), hi=wide)) == pytest.approx(37.3, abs=0.05)
    assert math.degrees(half_angle(lambda a: element_directivity(a, K, 4.75), hi=wide)) == pytest.approx(39.7, abs=0.05)
    assert math.degrees(half_angle(lambda a: element_directivity(a, K, 4.75), 2**-0.5, wide)) == \
        pytest.approx(27.8, abs=0.05)


@pytest.mark.parametrize("azimuth", range(0, 360, 15))
def test_array_half_angle_is_8_9_deg_at_every_azimuth(azimuth: int) -> None:
    a = half_angle(lambda x: array_directivity(x, math.radians(azimuth), K))
    assert math.degrees(a) == pytest.approx(8.9, abs=0.05)  # printed to 0.1 deg: half a unit
    b = half_angle(lambda x: array_directivity(x, math.radians(azimuth), K, radius=4.75))
    assert math.degrees(b) == pytest.approx(8.9, abs=0.05)        # insensitive to the element radius


def test_first_null_and_sidelobes() -> None:
    alpha = np.radians(np.arange(0.0, 40.0, 0.005))
    found = {}
    for azimuth in (0, 90):
        d = array_directivity(alpha, math.radians(azimuth), K)
        first_min = int(np.argmax(np.diff(d) > 0))
        found[azimuth] = (math.degrees(alpha[first_min]), d[first_min:].max())
    assert 15.1 <= found[0][0] <= 15.6 and 15.1 <= found[90][0] <= 15.7   # "main lobe +-15 deg"
    # the side lobes sampled every 0.005 deg: printed 0.24 (half a unit: 0.005) and 0.129 (with the
    # sampling of the lobe's peak: 0.002)
    assert found[0][1] == pytest.approx(0.24, abs=0.005)                  # -12 dB on the 0 deg axis
    assert found[90][1] == pytest.approx(0.129, abs=0.002)                # spec §6.7, a_eff = 5 mm


def test_array_sum_equals_the_pair_form_of_4_2() -> None:
    alpha, az = np.meshgrid(np.radians(np.linspace(0, 60, 41)), np.radians(np.linspace(0, 360, 37)))
    p, q = np.sin(alpha) * np.cos(az), np.sin(alpha) * np.sin(az)
    d, dp, c6, s6 = 9.5, math.sqrt(3) * 9.5, math.cos(math.pi / 6), math.sin(math.pi / 6)
    bracket = (np.cos(K * d * q) + 2 * np.cos(K * d * c6 * p) * np.cos(K * d * s6 * q) + np.cos(K * dp * p)
               + 2 * np.cos(K * dp * s6 * p) * np.cos(K * dp * c6 * q))
    pair = element_directivity(alpha, K) * np.abs(bracket) / 6     # (4.2): (1/3) (J1/x) [...] = D1/6 [...]
    # two sums of cosines weighted by the same D1 (|D| <= 1, terms <= 1): ~20 roundings apart
    np.testing.assert_allclose(array_directivity(alpha, az, K), pair, rtol=0, atol=roundoff(ops=20))


@pytest.mark.parametrize("psi, delta, gain", [(22.5, 3.5, 0.99), (45.0, 7.1, 0.98), (67.5, 10.6, 0.95),
                                              (90.0, 14.2, 0.91)])
def test_corrected_steering_moves_the_lobe_along_the_c_d_axis(psi: float, delta: float, gain: float) -> None:
    assert np.bincount(steering_groups() + 2).tolist() == [1, 4, 2, 4, 1]
    alpha, az = np.meshgrid(np.radians(np.arange(0, 25, 0.02)), np.radians(np.arange(0, 360, 0.5)))
    d = array_directivity(alpha, az, K, math.radians(psi))
    i = np.unravel_index(d.argmax(), d.shape)
    assert math.degrees(az[i]) == pytest.approx(300.0, rel=roundoff(ops=2))  # a grid azimuth: -e, the +2 psi group's side
    # the table's 0.1 deg and 2 decimals, and the grid (0.02 deg, 0.5 deg in azimuth) that samples the lobe
    assert math.degrees(alpha[i]) == pytest.approx(delta, abs=0.15)
    assert d.max() == pytest.approx(gain, abs=0.015)
    formula = math.degrees(math.asin(2 * math.radians(psi) / (math.sqrt(3) * K * 9.5)))
    assert 0.2 <= formula - math.degrees(alpha[i]) <= 1.1          # element directivity pulls it in


def test_echo_round_trip_at_1_3_m() -> None:
    assert float(round_trip(1300.0)) * 1000.0 == pytest.approx(7.6, abs=0.05)  # 2.6 m / 344 m/s = 7.56 ms, printed 7.6
    assert float(round_trip(1300.0, celsius=0.0)) > float(round_trip(1300.0, celsius=30.0))
