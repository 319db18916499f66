"""Registration of the film scanner: the ``film_scanner`` instrument, and the truth of a recording
made on the virtual lab (written under ``/truth/<instrument>`` when the recording stops).

Nothing else lives here.
"""

from __future__ import annotations

from typing import Any

from mirrorlab.core import hookimpl

from .driver import FilmScanner


@hookimpl
def mirrorlab_register_instruments() -> list[type]:
    return [FilmScanner]


@hookimpl
def mirrorlab_recording_stopped(session: Any, statistics: dict[str, Any]) -> None:
    from .virtual import record_all_truth  # imported when a recording ends, not at start-up

    record_all_truth(session)
