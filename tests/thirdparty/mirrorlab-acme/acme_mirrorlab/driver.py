"""The driver: typed settings, one stream, streaming through unsolicited lines."""

from __future__ import annotations

import queue
import threading
from typing import Any

import numpy as np
from mirrorlab.core import Parameter, ParameterSet, ProtocolError, StreamSpec
from mirrorlab.core.devices import SerialInstrument

from .model import AcmeThermometerModel


class AcmeThermometer(SerialInstrument):
    name = "acme_thermometer"
    version = "0.3.0"
    description = "ACME T-100 serial thermometer (streams temperature)"
    kind = "ATHM"
    simulator = AcmeThermometerModel
    parameters = ParameterSet(
        Parameter("rate", float, 10.0, unit="Hz", bounds=(1.0, 1000.0), help="samples per second"),
    )

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._samples: queue.Queue[tuple[float, float]] = queue.Queue(maxsize=100_000)

    def apply_settings(self, settings: dict[str, Any]) -> None:
        self.query(f"RATE {settings['rate']:g}")

    def streams(self) -> list[StreamSpec]:
        return [StreamSpec("temperature", "f8", (), "K", self.settings["rate"], "air temperature")]

    def on_unsolicited(self, line: str) -> None:
        if line.startswith("T "):
            try:
                _, ms, mk = line.split()
                self._samples.put_nowait((float(ms) / 1000.0, float(mk) / 1000.0))
            except (ValueError, queue.Full):
                self.report("warning", "bad_sample", f"{self.device_name}: unusable stream line {line!r}")
            return
        super().on_unsolicited(line)

    def acquire(self, emit: Any, stop: threading.Event) -> None:
        # Device clock (ms since power-up) -> session time, anchored once per acquisition.
        offset = emit.now() - float(self.query("TIME?").field(0, "ms")) / 1000.0
        self.query("STREAM ON")
        try:
            while not stop.is_set():
                if self.client is None or not self.client.alive:
                    self.query("PING")  # raises DeviceDisconnected: the base class reconnects
                batch = []
                try:
                    batch.append(self._samples.get(timeout=0.1))
                    while True:
                        batch.append(self._samples.get_nowait())
                except queue.Empty:
                    pass
                if batch:
                    times, values = np.array(batch).T
                    emit("temperature", times + offset, values)
        finally:
            if self.client is not None and self.client.alive:
                try:
                    self.query("STREAM OFF")
                except ProtocolError:
                    pass

    def read(self) -> dict[str, np.ndarray]:
        reply = self.query("READ?")
        return {"temperature": np.array([float(reply.field(1, "mK")) / 1000.0])}
