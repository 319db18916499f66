"""The common line protocol, pinned by the transcript of docs/instruments/connecting.md: sent in raw bytes over
a real TCP connection to a served simulator, answered byte for byte."""

from __future__ import annotations

from mirrorlab.core.devices import SimulatorServer
from mirrorlab.instruments.reference.models import ActuatorModel

from tests.instruments.transcripts import replay_on_server, transcripts

(CLIENT,) = transcripts("connecting.md")


def test_the_simulator_answers_the_documented_bytes() -> None:
    with SimulatorServer(ActuatorModel(seed=0), "tcp") as server:
        replay_on_server(server.url, CLIENT)
