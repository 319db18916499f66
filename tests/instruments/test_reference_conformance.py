"""The reference instruments pass the conformance kit over real pseudo-terminals."""

from __future__ import annotations

from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.reference import Actuator, AngleSource


class TestAngleSourceConformance(InstrumentConformance):
    instrument_class = AngleSource
    settings = {"rate": 200.0}


class TestActuatorConformance(InstrumentConformance):
    instrument_class = Actuator
    settings = {"rate": 100.0, "target": 0.5}
