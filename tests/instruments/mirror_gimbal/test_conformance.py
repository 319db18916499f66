"""The generic instrument conformance kit applied to MirrorGimbal (MGIM simulator over a pty)."""

from __future__ import annotations

from typing import Any

from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.mirror_gimbal import MirrorGimbal

from tests.instruments.faults import every_fault_while_acquiring
from tests.instruments.mirror_gimbal.test_model import EFFECTS


class TestMirrorGimbalConformance(InstrumentConformance):
    instrument_class = MirrorGimbal
    settings = {"mode_h": "track", "mode_v": "pos", "v_angle": 0.01}


def test_every_sim_fault_over_the_pty_while_acquiring(simulated_instrument: Any) -> None:
    """Each SIM:FAULT of the spec is accepted through the real driver and link while the gimbal
    streams, is listed by SIM:FAULT?, and acquisition goes on (a new block after each)."""
    with simulated_instrument(MirrorGimbal, {"mode_h": "track"}) as (inst, _):
        inst.configure()
        every_fault_while_acquiring(inst, "h", EFFECTS, "sample")
