"""Registration of the virtual lab's one hook: the truth of a session's shared tracking world,
written under ``/truth/world`` when a recording stops (:func:`.worlds.record_world_truth`).

The virtual lab registers no instrument; nothing else lives here.
"""

from __future__ import annotations

from typing import Any

from mirrorlab.core import hookimpl


@hookimpl
def mirrorlab_recording_stopped(session: Any, statistics: dict[str, Any]) -> None:
    from .worlds import record_world_truth  # imported when a recording ends, not at start-up

    record_world_truth(session)
