"""The conformance kit's streaming checks wait on events, and say so when a source is too short."""

from __future__ import annotations

import pytest
from mirrorlab.core.testing import InstrumentConformance, simulated
from mirrorlab.instruments.film_scanner import FilmScanner


class _ShortFilm(InstrumentConformance):
    instrument_class = FilmScanner
    settings = {"lines": 32, "scene_frames": 1}
    event_timeout = 30.0


def test_a_source_that_runs_out_fails_with_advice_instead_of_hanging() -> None:
    kit = _ShortFilm()
    with simulated(FilmScanner, dict(kit.settings)) as sim:
        with pytest.raises(pytest.fail.Exception, match="give the simulator enough material"):
            kit.test_acquisition_survives_disconnect(sim)


@pytest.mark.slow
def test_acquisition_survives_many_disconnects_mid_film() -> None:
    """Each disconnect comes on a block, mid-film; a hung-up port may fail in the driver's write,
    read or flush (pyserial lets termios.error out of flush): all must end in a reconnect."""
    kit = _ShortFilm()
    kit.settings = {"lines": 32, "scene_frames": 2000}
    kit.disconnects = 20
    with simulated(FilmScanner, dict(kit.settings)) as sim:
        kit.test_acquisition_survives_disconnect(sim)
