"""The ANGS wire format, pinned by the transcripts of docs/instruments/reference.md.

The first is replayed on the simulator (byte-identical replies and stream lines for seed 0); the second is
served by a scripted device on a real pty to the real driver, which must send exactly its bytes.
"""

from __future__ import annotations

from mirrorlab.instruments.reference import AngleSource
from mirrorlab.instruments.reference.models import AngleSourceModel

from tests.instruments.transcripts import replay_on_model, scripted_driver, transcripts

SIMULATOR, DRIVER = [t for t in transcripts("reference.md") if any("ANGS" in line for line in t)]


def test_simulator_answers_the_documented_transcript() -> None:
    replay_on_model(AngleSourceModel(seed=0), SIMULATOR)


def test_driver_sends_the_documented_bytes() -> None:
    with scripted_driver(DRIVER, AngleSource, "angle") as source:
        pass
    assert source.identity is not None and (source.identity.kind, source.identity.model) == ("ANGS", "ANG-1")
