"""The conformance kit run on the third-party example plugin (imported from its source folder)."""

from __future__ import annotations

import sys

from mirrorlab.core.testing import InstrumentConformance

from tests.support import THIRDPARTY

# Import the example plugin from its source folder without leaving that folder on sys.path, so
# entry-point discovery in other tests only sees installed distributions.
_SOURCE = str(THIRDPARTY / "mirrorlab-acme")
sys.path.insert(0, _SOURCE)
try:
    from acme_mirrorlab import AcmeThermometer
finally:
    sys.path.remove(_SOURCE)


class TestAcmeOverPty(InstrumentConformance):
    instrument_class = AcmeThermometer
    settings = {"rate": 200.0}


class TestAcmeOverTcp(InstrumentConformance):
    instrument_class = AcmeThermometer
    settings = {"rate": 200.0}
    transport = "tcp"
