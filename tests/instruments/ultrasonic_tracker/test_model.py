"""The USDF simulator against the thesis's figures (§2.4-§2.8, §5): in process, seeded.

Measured: the 80 ms search cycle at 1.3 m, the search from 12 deg off axis (Fig. 4.19), the loss
rates without servo (theory 31.25 deg/s) and with the calibrated servo (0.48 rad/s = 27.5 deg/s),
echo identification against left-over and background echoes, and every SIM:FAULT's effect.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from mirrorlab.instruments.ultrasonic_tracker import UltrasonicTrackerModel
from mirrorlab.instruments.ultrasonic_tracker.experiments import cycle_times, search_path, tracking_limit
from mirrorlab.instruments.ultrasonic_tracker.model import FAULTS


def test_search_cycle_takes_80_ms_at_1_3_m() -> None:
    cycles = cycle_times(cycles=40)
    # the thesis's ~80 ms at 1.3 m; the random emission period (sd a few ms) averages over 40 cycles
    assert cycles.mean() == pytest.approx(0.080, abs=0.002)
    assert cycles.std() > 0.001                   # the random emission period varies every cycle


def test_search_from_12_deg_converges_on_a_near_straight_path() -> None:
    path = np.degrees(search_path(cycles=30))
    # converged on (0, 12) deg to within the last steps' size (the recipe's final-error bound, 1.5 deg)
    assert path[-1, 1] == pytest.approx(12.0, abs=1.5) and abs(path[-1, 0]) < 1.5
    assert np.abs(path[:, 0]).max() < 1.0          # Fig. 4.19: almost straight along theta2
    assert np.all(np.diff(path[:12, 1]) >= 0)      # climbing steadily


def test_loss_rates_without_and_with_servo() -> None:
    free = math.degrees(tracking_limit(servo=None))
    assert 30.0 <= free <= 33.5, free              # theory 31.25 deg/s (measured 32.2)
    servoed = math.degrees(tracking_limit())
    assert servoed == pytest.approx(27.5, abs=1.0)  # 0.48 rad/s (measured 27.9)


def test_identification_ignores_left_overs_but_not_a_nearer_reflector() -> None:
    model = UltrasonicTrackerModel(seed=1)
    model.execute("SIM:FAULT LEFTOVER 0.5 40")
    model.execute("EMIT")
    emitted = model.execute("EMIT")                 # hears the room echoes of the first emission
    assert len(emitted) > 3, emitted                # direct wave, target and left-overs
    assert model.execute("IDENT") == ["OK 7.56"]    # left-overs do not line up: the target is found
    model.execute("SIM:FAULT BGECHO 20 0 900 2")
    assert model.execute("IDENT") == ["OK 5.23"]    # a static reflector nearer than the target wins


def test_no_target_is_e20_and_unaligned_arrivals_are_e21() -> None:
    model = UltrasonicTrackerModel(seed=2)
    model.execute("SIM:LOAD STILL 0 0 60000")       # far out of range: nothing but the direct wave
    assert model.execute("IDENT")[0].startswith("ERR E20")
    assert model.execute("MEAS?")[0].startswith("ERR E20")
    model.execute("SIM:LOAD STILL 0 0 1300")
    model.execute("SIM:FAULT WIND 40")               # arrivals jitter: the two emissions disagree
    assert model.execute("IDENT")[0].startswith("ERR E21")


def test_background_echo_coinciding_with_the_target_gives_a_wrong_gradient() -> None:
    def first_step(fault: str | None) -> np.ndarray:
        model = UltrasonicTrackerModel(seed=3, servo=None)
        model.execute("SIM:LOAD STILL 0 6 1300")
        if fault:
            model.execute(f"SIM:FAULT {fault}")
        model.execute("IDENT")
        sa, sb, sc, sd, _ = (float(x) for x in model.execute("MEAS?")[0].split()[1:])
        return np.array([-(sa - sb + sc - sd), sa - sb - sc + sd])

    clean, spoiled = first_step(None), first_step("BGECHO 0 -12 1300 3")
    assert clean[1] > 0                             # toward the target, up in theta2
    assert spoiled[1] < 0                           # the reflector below at the same range wins


def test_step_is_inversely_proportional_to_pressure() -> None:
    model = UltrasonicTrackerModel(seed=0, servo=None)
    model.execute("SIM:LOAD STILL 0 10 1300")
    model.execute("STREAM ON")
    model.execute("TRACK ON")
    model.advance(2.0)
    rows = np.array([[float(x) for x in l.split()[2:5]] for l in model.stream_lines() if l.startswith("!TRK")])
    steps = np.hypot(*np.diff(rows[:, :2], axis=0).T)
    far, near = steps[0], np.median(steps[-8:])
    # the first step is the model's 2.5 deg at the start pressure, +-0.35 for the noise of the four readings
    assert far == pytest.approx(2.5, abs=0.35) and near < 0.6 * far and rows[-1, 2] > 2 * rows[0, 2]


def test_aim_quantisation_and_range() -> None:
    model = UltrasonicTrackerModel()
    assert model.execute("AIM 1 -2") == ["OK 0.9375 -1.8750"]
    assert model.execute("AIM 41 0")[0].startswith("ERR E03")
    assert model.execute("PSI 45") == ["OK 44.64 7.45"]
    model.execute("TRACK ON")
    assert model.execute("AIM 0 0")[0].startswith("ERR E04")
    assert model.execute("AIM?")[0].startswith("OK")


def probe(fault: str) -> list[str]:
    model = UltrasonicTrackerModel(seed=5)
    model.execute("SIM:LOAD CIRCLE 0 10 1300 0.2")
    if fault:
        assert model.execute(f"SIM:FAULT {fault}") == ["OK"], fault
    model.execute("STREAM ON")
    model.execute("TRACK ON")
    model.advance(1.5)
    model.execute("TRACK OFF")
    return model.stream_lines() + model.execute("EMIT") + model.execute("SIM:TRUTH?")


EFFECTS = ["BGECHO 10 0 1300 1", "LEFTOVER 0.5 40", "FLAT 0 0", "SIDELOBE 3", "TEMP 0", "NOISE 30",
           "SERVOGAIN 1 0.3", "WIND 10"]


def test_every_spec_fault_is_covered() -> None:
    assert sorted(f.split()[0] for f in EFFECTS) == sorted(FAULTS)


@pytest.mark.parametrize("fault", EFFECTS)
def test_every_fault_changes_what_the_device_reports(fault: str) -> None:
    assert probe(fault) != probe("")


def test_temperature_sets_the_speed_of_sound() -> None:
    model = UltrasonicTrackerModel()
    model.execute("SIM:FAULT TEMP 0")
    assert model.execute("IDENT") == [f"OK {2 * 1300 / 331.5:.2f}"]


def test_same_seed_same_replies() -> None:
    assert probe("WIND 10") == probe("WIND 10")
