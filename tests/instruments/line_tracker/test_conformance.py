"""The generic instrument conformance kit applied to LineTracker (OLDT simulator over a pty), and
every SIM:FAULT of the spec injected through the real driver while it streams."""

from __future__ import annotations

from typing import Any

from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.line_tracker import LineTracker

from tests.instruments.faults import every_fault_while_acquiring
from tests.instruments.line_tracker.test_model import EFFECTS


class TestLineTrackerConformance(InstrumentConformance):
    instrument_class = LineTracker
    settings = {"auto": "on", "d_ref": 170}


def test_every_sim_fault_over_the_pty_while_acquiring(simulated_instrument: Any) -> None:
    with simulated_instrument(LineTracker, {}) as (inst, _):
        inst.configure()
        every_fault_while_acquiring(inst, "mark", EFFECTS, "scan")
