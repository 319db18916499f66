"""The generic instrument conformance kit applied to FilmScanner (FSCAN simulator over a pty)."""

from __future__ import annotations

from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.film_scanner import FilmScanner


class TestFilmScannerConformance(InstrumentConformance):
    instrument_class = FilmScanner
    settings = {"lines": 64}
    acquire_seconds = 2.0
