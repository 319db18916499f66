"""The generic instrument conformance kit applied to UltrasonicTracker (USDF simulator over a pty),
and every SIM:FAULT of the spec injected through the real driver while it streams."""

from __future__ import annotations

from typing import Any

from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.ultrasonic_tracker import UltrasonicTracker

from tests.instruments.faults import every_fault_while_acquiring
from tests.instruments.ultrasonic_tracker.test_model import EFFECTS


class TestUltrasonicConformance(InstrumentConformance):
    instrument_class = UltrasonicTracker
    settings = {"track": True}


def test_every_sim_fault_over_the_pty_while_acquiring(simulated_instrument: Any) -> None:
    with simulated_instrument(UltrasonicTracker, {}) as (inst, _):
        inst.configure()
        every_fault_while_acquiring(inst, "direction", EFFECTS, "search cycle")
