"""The ACTU wire format, pinned by the transcripts of docs/instruments/reference.md.

The first is replayed on the simulator (byte-identical replies and stream lines for seed 0); the second is
served by a scripted device on a real pty to the real driver, which must send exactly its bytes (a live
set-point sends ``TGT`` alone, in integer µrad).
"""

from __future__ import annotations

import math

import pytest
from mirrorlab.instruments.reference import Actuator
from mirrorlab.instruments.reference.models import ActuatorModel

from tests.instruments.transcripts import replay_on_model, scripted_driver, transcripts

SIMULATOR, DRIVER = [t for t in transcripts("reference.md") if any("ACTU" in line for line in t)]


def test_simulator_answers_the_documented_transcript() -> None:
    replay_on_model(ActuatorModel(seed=0), SIMULATOR)


def test_driver_sends_the_documented_bytes() -> None:
    with scripted_driver(DRIVER, Actuator, "act") as actuator:
        applied = actuator.set("target", math.radians(6.0)).wait()
        actuator.hold()
        reading = actuator.read()
    assert applied == math.radians(6.0)
    assert reading["position"].tolist() == pytest.approx([2095e-6], rel=1e-15)   # µrad -> rad: one rounding
