"""The generic instrument conformance kit applied to LineTracker (OLDT simulator over a pty), and
every SIM:FAULT of the spec injected through the real driver while it streams."""

from __future__ import annotations

from typing import Any

from mirrorlab.core.clock import SessionClock
from mirrorlab.core.streams import Emitter, StreamRouter
from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.line_tracker import LineTracker

from tests.instruments.test_line_tracker_model import EFFECTS


class TestLineTrackerConformance(InstrumentConformance):
    instrument_class = LineTracker
    settings = {"auto": "on", "d_ref": 170}


def test_every_sim_fault_over_the_pty_while_acquiring(simulated_instrument: Any) -> None:
    with simulated_instrument(LineTracker, {}) as (inst, _):
        inst.configure()
        router, clock = StreamRouter(), SessionClock()
        specs = {s.name: s for s in inst.streams()}
        sub = router.subscribe([("dut", "mark")], max_bytes=1 << 28)
        inst.start(Emitter("dut", router, clock, specs))
        try:
            for fault in sorted(EFFECTS):
                assert inst.simulate_query(f"SIM:FAULT {fault}").fields == []
                before = clock.now()
                block = None
                while block is None or block.times[-1] <= before:
                    block = sub.get(timeout=30.0)
                    assert block is not None, f"no scan after SIM:FAULT {fault}"
            assert len(inst.simulate_query("SIM:FAULT?").data) == len(EFFECTS)
        finally:
            inst.stop()
        assert inst.failed is None
