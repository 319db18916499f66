"""The driver: typed settings, one stream, streaming through unsolicited lines."""

from __future__ import annotations

from typing import Any

import numpy as np
from mirrorlab.core import Parameter, ParameterSet, StreamSpec
from mirrorlab.core.devices import StreamingInstrument, StreamSample

from .model import AcmeThermometerModel


class AcmeThermometer(StreamingInstrument):
    name = "acme_thermometer"
    version = "0.3.0"
    description = "ACME T-100 serial thermometer (streams temperature)"
    kind = "ATHM"
    simulator = AcmeThermometerModel
    parameters = ParameterSet(
        Parameter("rate", float, 10.0, unit="Hz", bounds=(1.0, 1000.0), help="samples per second"),
    )

    def apply_settings(self, settings: dict[str, Any]) -> None:
        self.query(f"RATE {settings['rate']:g}")

    def streams(self) -> list[StreamSpec]:
        return [StreamSpec("temperature", "f8", (), "K", self.settings["rate"], "air temperature")]

    def parse_stream_line(self, line: str) -> StreamSample | None:
        if not line.startswith("T "):
            return None
        _, ms, mk = line.split()
        return StreamSample("temperature", float(ms) / 1000.0, float(mk) / 1000.0)

    def read(self) -> dict[str, np.ndarray]:
        reply = self.query("READ?")
        return {"temperature": np.array([float(reply.field(1, "mK")) / 1000.0])}
