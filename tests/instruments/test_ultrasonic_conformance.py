"""The generic instrument conformance kit applied to UltrasonicTracker (USDF simulator over a pty),
and every SIM:FAULT of the spec injected through the real driver while it streams."""

from __future__ import annotations

from typing import Any

from mirrorlab.core.clock import SessionClock
from mirrorlab.core.streams import Emitter, StreamRouter
from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.ultrasonic_tracker import UltrasonicTracker

from tests.instruments.test_ultrasonic_model import EFFECTS


class TestUltrasonicConformance(InstrumentConformance):
    instrument_class = UltrasonicTracker
    settings = {"track": True}


def test_every_sim_fault_over_the_pty_while_acquiring(simulated_instrument: Any) -> None:
    with simulated_instrument(UltrasonicTracker, {}) as (inst, _):
        inst.configure()
        router, clock = StreamRouter(), SessionClock()
        specs = {s.name: s for s in inst.streams()}
        sub = router.subscribe([("dut", "direction")], max_bytes=1 << 28)
        inst.start(Emitter("dut", router, clock, specs))
        try:
            for fault in sorted(EFFECTS):
                assert inst.simulate_query(f"SIM:FAULT {fault}").fields == []
                before = clock.now()
                block = None
                while block is None or block.times[-1] <= before:
                    block = sub.get(timeout=30.0)
                    assert block is not None, f"no search cycle after SIM:FAULT {fault}"
            assert len(inst.simulate_query("SIM:FAULT?").data) == len(EFFECTS)
        finally:
            inst.stop()
        assert inst.failed is None
