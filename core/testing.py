"""The instrument conformance kit: a pytest plugin every instrument plugin's tests use.

Installed with mirrorlab (entry point ``pytest11``), it provides the fixture
``simulated_instrument`` and the test class :class:`InstrumentConformance`. Subclass it in your
plugin's tests, name your instrument class and settings, and pytest runs the generic checks
against your simulator, through a real pseudo-terminal (or TCP socket) and your real driver::

    from mirrorlab.core.testing import InstrumentConformance
    from acme_mirrorlab import AcmeTracker

    class TestAcmeConformance(InstrumentConformance):
        instrument_class = AcmeTracker
        settings = {"rate": 50.0}

Checks: connect/close idempotent; identity and metadata complete; settings round-trip;
``status``; declared streams are emitted with session timestamps; a stalled device raises
:class:`DeviceTimeout`; garbage raises :class:`ProtocolError` and is counted; a disconnect is
reported as :class:`DeviceDisconnected` and ``reconnect()`` recovers; acquisition survives a
disconnect by reconnecting.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, ClassVar

import numpy as np
import pytest

from .clock import SessionClock
from .devices import Instrument, SerialInstrument, SimulatorServer
from .errors import DeviceDisconnected, DeviceError, DeviceTimeout, ProtocolError
from .streams import Emitter, StreamRouter


@contextmanager
def simulated(instrument_class: type[Instrument], settings: dict[str, Any] | None = None, transport: str = "pty",
              seed: int = 0, timeout: float = 1.0) -> Iterator[tuple[Instrument, SimulatorServer]]:
    """Start ``instrument_class``'s simulator and yield ``(connected instrument, server)``.

    The simulator clock is FAST so modelled delays cost no wall time.
    """
    inst = instrument_class("dut", None, settings or {}, timeout)
    make = getattr(instrument_class, "make_simulator", None)
    model = make(inst.settings, seed) if make else instrument_class.simulator(seed=seed)
    with SimulatorServer(model, transport) as server:
        inst.port = server.url
        try:
            inst.connect()
            if isinstance(inst, SerialInstrument):
                inst.simulate_query("SIM:CLOCK FAST")
            yield inst, server
        finally:
            inst.stop()
            inst.close()


@pytest.fixture
def simulated_instrument() -> Any:
    """Factory fixture: ``with simulated_instrument(MyInstrument, {...}) as (inst, server): ...``."""
    return simulated


class InstrumentConformance:
    """Generic checks for a serial instrument plugin against its simulator (subclass it)."""

    instrument_class: ClassVar[type[SerialInstrument]]
    settings: ClassVar[dict[str, Any]] = {}
    transport: ClassVar[str] = "pty"
    #: Seconds of acquisition used by the streaming checks.
    acquire_seconds: ClassVar[float] = 1.0

    @pytest.fixture
    def sim(self) -> Iterator[tuple[SerialInstrument, SimulatorServer]]:
        with simulated(self.instrument_class, dict(self.settings), self.transport) as pair:
            yield pair

    # -- declarations ------------------------------------------------------------------------------
    def test_declares_plugin_metadata(self) -> None:
        cls = self.instrument_class
        for attr in ("name", "version", "description"):
            assert isinstance(getattr(cls, attr, None), str) and getattr(cls, attr), f"{cls} lacks {attr}"
        assert cls.simulator is not None or hasattr(cls, "make_simulator"), "an instrument plugin ships a simulator"
        for p in cls.parameters:
            assert p.help, f"parameter {p.name!r} needs help text (CLI, TUI forms)"

    # -- lifecycle ---------------------------------------------------------------------------------
    def test_connect_and_close_are_idempotent(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, _ = sim
        inst.connect()
        inst.connect()
        assert inst.query("PING").fields == ["PONG"]
        inst.close()
        inst.close()
        with pytest.raises(DeviceDisconnected):
            inst.query("PING")
        inst.connect()
        assert inst.query("PING").fields == ["PONG"]

    def test_identity_and_metadata_complete(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, _ = sim
        identity = inst.identify()
        assert identity.kind == self.instrument_class.kind
        assert all(identity.as_dict().values()), identity
        meta = inst.metadata()
        assert meta["plugin"] == self.instrument_class.name and meta["version"] and meta["identity"]

    def test_settings_round_trip(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, _ = sim
        applied = inst.configure()
        assert applied == inst.parameters.validate(dict(self.settings))
        again = inst.configure(**applied)
        assert again == applied

    def test_status(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, _ = sim
        status = inst.status()
        assert status.state and status.connected

    # -- faults ------------------------------------------------------------------------------------
    def test_timeout_raises(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, server = sim
        server.endpoint.faults.stall = True
        started = time.monotonic()
        with pytest.raises(DeviceTimeout, match="did not answer"):
            inst.query("PING", timeout=0.3)
        assert time.monotonic() - started < 2.0
        server.endpoint.faults.stall = False

    def test_garbage_is_reported(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, server = sim
        server.endpoint.faults.garble = 0.2
        errors: set[type] = set()
        for _ in range(20):  # garbled newlines give timeouts; garbled text gives ProtocolError
            try:
                inst.identify()
            except (ProtocolError, DeviceTimeout) as exc:
                errors.add(type(exc))
            if ProtocolError in errors:
                break
        server.endpoint.faults.garble = 0.0
        assert ProtocolError in errors, "garbled replies must raise ProtocolError"
        assert inst.client is not None and inst.client.garbage_lines > 0
        assert inst.query("PING").fields == ["PONG"]  # the client resynchronises by itself

    def test_disconnect_is_reported_and_reconnect_works(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, server = sim
        server.disconnect()
        with pytest.raises((DeviceDisconnected, DeviceTimeout)):
            for _ in range(3):
                inst.query("PING", timeout=0.5)
        inst.reconnect()
        assert inst.query("PING").fields == ["PONG"]

    # -- streaming ---------------------------------------------------------------------------------
    def _acquire(self, inst: SerialInstrument, seconds: float) -> tuple[StreamRouter, Any]:
        """Acquire for ``seconds``, then on until every stream has emitted (a busy machine is slow)."""
        router, clock = StreamRouter(), SessionClock()
        specs = {s.name: s for s in inst.streams()}
        subs = {name: router.subscribe("dut", name, maxlen=100_000) for name in specs}
        inst.start(Emitter("dut", router, clock, specs))
        time.sleep(seconds)
        deadline = time.monotonic() + 10 + 20 * seconds
        while (any(("dut", name) not in router.stats for name in specs) and inst.failed is None
               and time.monotonic() < deadline):
            time.sleep(0.05)
        inst.stop()
        return router, subs

    def test_streams_are_declared_and_emitted(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, _ = sim
        inst.configure()
        specs = {s.name: s for s in inst.streams()}
        assert specs, "an instrument declares at least one stream"
        _, subs = self._acquire(inst, self.acquire_seconds)
        assert inst.failed is None, inst.failed
        for name, spec in specs.items():
            blocks = subs[name].drain()
            assert blocks, f"stream {name!r} emitted nothing"
            times = np.concatenate([b.times for b in blocks])
            assert np.all(np.diff(times) >= 0), f"stream {name!r} times go backwards"
            values = np.concatenate([b.values.reshape(-1, *spec.shape) for b in blocks])
            assert values.shape[1:] == tuple(spec.shape)
            assert len(values) == len(times)

    def test_acquisition_survives_disconnect(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, server = sim
        inst.configure()
        events: list[str] = []
        messages: list[str] = []
        inst.report = lambda level, kind, message, **data: (events.append(kind), messages.append(message))
        router, clock = StreamRouter(), SessionClock()
        specs = {s.name: s for s in inst.streams()}
        inst.start(Emitter("dut", router, clock, specs))
        time.sleep(self.acquire_seconds / 2)
        threading.Thread(target=server.disconnect).start()
        deadline = time.monotonic() + 10
        while "reconnected" not in events and time.monotonic() < deadline and inst.failed is None:
            time.sleep(0.05)
        def samples() -> int:
            return sum(st.samples for st in router.stats.values())

        before = samples()
        deadline = time.monotonic() + 10 + 20 * self.acquire_seconds  # generous: CI machines are busy
        while samples() == before and time.monotonic() < deadline and inst.failed is None:
            time.sleep(0.05)
        after = samples()
        inst.stop()
        assert "connection_lost" in events and "reconnected" in events, messages
        assert inst.failed is None, messages
        assert after > before, "no samples after the reconnect"


__all__ = ["InstrumentConformance", "simulated", "DeviceError"]
