"""Every ``SIM:FAULT`` of a spec injected through an instrument's real driver while it streams."""

from __future__ import annotations

from collections.abc import Collection

from mirrorlab.core.clock import SessionClock
from mirrorlab.core.devices import StreamingInstrument
from mirrorlab.core.streams import Emitter, StreamRouter


def every_fault_while_acquiring(inst: StreamingInstrument, stream: str, faults: Collection[str], sample: str) -> None:
    """Start ``inst`` (connected, configured) and set each of ``faults`` through it: each is accepted, a new
    block of ``stream`` (a ``sample``: scan, search cycle...) arrives after it, ``SIM:FAULT?`` lists them
    all, and the acquisition never fails."""
    router, clock = StreamRouter(), SessionClock()
    specs = {s.name: s for s in inst.streams()}
    sub = router.subscribe([("dut", stream)], max_bytes=1 << 28)
    inst.start(Emitter("dut", router, clock, specs))
    try:
        for fault in sorted(faults):
            assert inst.simulate_query(f"SIM:FAULT {fault}").fields == []
            before = clock.now()
            block = None
            while block is None or block.times[-1] <= before:
                block = sub.get(timeout=30.0)
                assert block is not None, f"no {sample} after SIM:FAULT {fault}"
        assert len(inst.simulate_query("SIM:FAULT?").data) == len(faults)
    finally:
        inst.stop()
    assert inst.failed is None
