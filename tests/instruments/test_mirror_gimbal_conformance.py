"""The generic instrument conformance kit applied to MirrorGimbal (MGIM simulator over a pty)."""

from __future__ import annotations

from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.mirror_gimbal import MirrorGimbal


class TestMirrorGimbalConformance(InstrumentConformance):
    instrument_class = MirrorGimbal
    settings = {"mode_h": "track", "mode_v": "pos", "v_angle": 0.01}


def test_every_sim_fault_over_the_pty_while_acquiring(simulated_instrument) -> None:  # type: ignore[no-untyped-def]
    """Each SIM:FAULT of the spec is accepted through the real driver and link while the gimbal
    streams, is listed by SIM:FAULT?, and acquisition goes on (a new block after each)."""
    from mirrorlab.core.clock import SessionClock
    from mirrorlab.core.streams import Emitter, StreamRouter

    from tests.instruments.test_mirror_gimbal_model import EFFECTS

    with simulated_instrument(MirrorGimbal, {"mode_h": "track"}) as (inst, _):
        inst.configure()
        router, clock = StreamRouter(), SessionClock()
        specs = {s.name: s for s in inst.streams()}
        sub = router.subscribe([("dut", "h")], max_bytes=1 << 28)
        inst.start(Emitter("dut", router, clock, specs))
        try:
            for fault in sorted(EFFECTS):
                assert inst.simulate_query(f"SIM:FAULT {fault}").fields == []
                before = clock.now()
                block = None
                while block is None or block.times[-1] <= before:
                    block = sub.get(timeout=30.0)
                    assert block is not None, f"no sample after SIM:FAULT {fault}"
            listed = inst.simulate_query("SIM:FAULT?").data
            assert len(listed) == len(EFFECTS)
        finally:
            inst.stop()
        assert inst.failed is None
