"""The generic instrument conformance kit applied to FilmScanner (FSCAN simulator over a pty)."""

from __future__ import annotations

from mirrorlab.core.testing import InstrumentConformance
from mirrorlab.instruments.film_scanner import FilmScanner


class TestFilmScannerConformance(InstrumentConformance):
    instrument_class = FilmScanner
    # A long film (rendered lazily, frame by frame) so that the streaming checks never meet its end.
    settings = {"lines": 64, "scene_frames": 10_000}
