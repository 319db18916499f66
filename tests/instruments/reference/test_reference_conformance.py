"""The reference instruments pass the conformance kit over real pseudo-terminals."""

from __future__ import annotations

from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.reference import Actuator, AngleSource, ChainSource


class TestAngleSourceConformance(InstrumentConformance):
    instrument_class = AngleSource
    settings = {"rate": 200.0}


class TestActuatorConformance(InstrumentConformance):
    instrument_class = Actuator
    settings = {"rate": 100.0, "target": 0.5}


class TestChainSourceConformance(InstrumentConformance):
    instrument_class = ChainSource
    settings = {"rate": 200.0, "joints": "shoulder,elbow,hand"}
