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
reported as :class:`DeviceDisconnected` and ``reconnect()`` recovers; acquisition survives
``disconnects`` unplug/replug cycles, each reconnecting at the first attempt; ``stop()`` ends
acquisition within the instrument's ``stop_timeout`` with its state ``stopped``; every live
parameter is accepted by ``set()`` (acknowledged by the device) without re-sending the others.

The streaming checks wait on what the instrument does (a block emitted, a reconnect reported, its
thread ending), never on elapsed time, so a busy machine only makes them slower. ``event_timeout``
(60 s) only turns a hang into a failure. A finite simulated source must hold enough material for
the checks (a few blocks per disconnect): if it runs out, the check fails and says so.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, ClassVar, TypeVar

import numpy as np
import pytest

from .clock import SessionClock
from .devices import Instrument, SerialInstrument, SimulatorServer
from .errors import DeviceDisconnected, DeviceError, DeviceTimeout, ProtocolError, ValidationError
from .streams import Block, Emitter, StreamRouter, Subscription

#: The instrument class a helper was given, and so the instance it hands back.
I = TypeVar("I", bound=Instrument)


@contextmanager
def simulated(instrument_class: type[I], settings: dict[str, Any] | None = None, transport: str = "pty",
              seed: int = 0, timeout: float = 1.0) -> Iterator[tuple[I, SimulatorServer]]:
    """Start ``instrument_class``'s simulator and yield ``(connected instrument, server)``.

    The simulator clock is FAST so modelled delays cost no wall time.
    """
    inst = instrument_class("dut", None, settings or {}, timeout)
    model = instrument_class.make_simulator(inst.settings, seed)
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
    #: Longest wait for any one event (a block, a reconnect) before a streaming check fails. Only a
    #: hang detector: the checks proceed as soon as the event happens.
    event_timeout: ClassVar[float] = 60.0
    #: Disconnects (each followed by a reconnect and a new sample) in the reconnect check.
    disconnects: ClassVar[int] = 3

    @pytest.fixture
    def sim(self) -> Iterator[tuple[SerialInstrument, SimulatorServer]]:
        with simulated(self.instrument_class, dict(self.settings), self.transport) as pair:
            yield pair

    # -- declarations ------------------------------------------------------------------------------
    def test_declares_plugin_metadata(self) -> None:
        cls = self.instrument_class
        for attr in ("name", "version", "description"):
            assert isinstance(getattr(cls, attr, None), str) and getattr(cls, attr), f"{cls} lacks {attr}"
        assert cls.has_simulator(), "an instrument plugin ships a simulator (set `simulator` or override make_simulator)"
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
    # These checks wait on what the instrument does (a block emitted, an event reported, the thread
    # ending), never on elapsed time: ``event_timeout`` only turns a hang into a failure.

    def _start(self, inst: SerialInstrument) -> tuple[StreamRouter, SessionClock, dict[str, Subscription], _Reports]:
        router, clock = StreamRouter(), SessionClock()
        specs = {s.name: s for s in inst.streams()}
        subs = {name: router.subscribe([("dut", name)], max_bytes=1 << 30) for name in specs}
        reports = _Reports()
        inst.report = reports
        inst.start(Emitter("dut", router, clock, specs))
        return router, clock, subs, reports

    def _next_block(self, inst: SerialInstrument, sub: Subscription, reports: _Reports, when: str,
                    after: float = -np.inf) -> Block:
        """The next block of ``sub`` stamped later than ``after``; fails if the instrument ends first."""
        deadline = time.monotonic() + self.event_timeout
        while time.monotonic() < deadline:
            block = sub.get(timeout=0.05)
            if block is not None and block.times[-1] > after:
                return block
            if block is None and not inst.running:
                pytest.fail(f"stream {sub.stream!r} emitted nothing {when}: the acquisition ended "
                            f"({inst.failed or 'the source ran out'}); give the simulator enough material "
                            f"in `settings` for the check. Instrument messages: {reports.messages}")
        pytest.fail(f"stream {sub.stream!r} emitted nothing {when} within {self.event_timeout:g} s. "
                    f"Instrument messages: {reports.messages}")

    def test_streams_are_declared_and_emitted(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, _ = sim
        inst.configure()
        specs = {s.name: s for s in inst.streams()}
        assert specs, "an instrument declares at least one stream"
        _, _, subs, reports = self._start(inst)
        seen: dict[str, list[Block]] = {name: [] for name in specs}
        try:
            for name in specs:  # each stream twice, so the time order is checked across blocks too
                seen[name].append(self._next_block(inst, subs[name], reports, "after start"))
                seen[name].append(self._next_block(inst, subs[name], reports, "after its first block"))
        finally:
            inst.stop()
        assert inst.failed is None, reports.messages
        for name, spec in specs.items():
            blocks = seen[name] + subs[name].drain()
            times = np.concatenate([b.times for b in blocks])
            assert np.all(np.diff(times) >= 0), f"stream {name!r} times go backwards"
            values = np.concatenate([b.values.reshape(-1, *spec.shape) for b in blocks])
            assert values.shape[1:] == tuple(spec.shape)
            assert len(values) == len(times)

    def test_stop_ends_acquisition_promptly(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, _ = sim
        inst.configure()
        _, _, subs, reports = self._start(inst)
        self._next_block(inst, next(iter(subs.values())), reports, "after start")
        inst.stop()
        assert not inst.running and inst.state == "stopped" and inst.failed is None, reports.messages
        assert "stop_timeout" not in reports.kinds, reports.messages

    def test_live_parameters_are_set_one_at_a_time(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, _ = sim
        inst.configure()
        for name in inst.parameters.setpoints:
            before = {k: v for k, v in inst.settings.items() if k != name}
            status = inst.set(name, inst.settings[name])
            assert status.wait() == inst.settings[name] and status.success, status
            assert {k: v for k, v in inst.settings.items() if k != name} == before
        fixed = [p.name for p in inst.parameters if p.name not in inst.parameters.setpoints]
        if fixed:
            with pytest.raises(ValidationError, match="not live-settable"):
                inst.set(fixed[0], inst.settings[fixed[0]])

    def test_acquisition_survives_disconnect(self, sim: tuple[SerialInstrument, SimulatorServer]) -> None:
        inst, server = sim
        inst.configure()
        _, clock, subs, reports = self._start(inst)
        sub = next(iter(subs.values()))
        try:
            self._next_block(inst, sub, reports, "before the first disconnect")
            for n in range(1, self.disconnects + 1):
                server.disconnect()  # while the device is streaming: the driver meets it mid-acquisition
                if not reports.wait_for("reconnected", n, self.event_timeout, inst):
                    why = (f"the acquisition ended ({inst.failed or 'the source ran out'}); give the simulator "
                           "enough material in `settings` for the check" if not inst.running
                           else f"nothing within {self.event_timeout:g} s")
                    pytest.fail(f"no reconnect after disconnect {n}: {why}. Instrument messages: {reports.messages}")
                self._next_block(inst, sub, reports, f"after reconnect {n}",
                                 after=clock.from_monotonic(reports.last_at("reconnected")))
        finally:
            inst.stop()
        assert reports.kinds.count("connection_lost") >= self.disconnects, reports.messages
        assert inst.failed is None, reports.messages
        assert inst.reconnects == self.disconnects
        # The simulator is back at once, so the first attempt must succeed; a retry means stale bytes of
        # the old connection were taken for the new one's replies.
        assert "reconnect_retry" not in reports.kinds, reports.messages


class _Reports:
    """An instrument's reporter that records events and lets a test wait for them."""

    def __init__(self) -> None:
        self.kinds: list[str] = []
        self.messages: list[str] = []
        self._last_at: dict[str, float] = {}
        self._cond = threading.Condition()

    def __call__(self, level: str, kind: str, message: str, **data: Any) -> None:
        with self._cond:
            self.kinds.append(kind)
            self.messages.append(message)
            self._last_at[kind] = time.monotonic()
            self._cond.notify_all()

    def wait_for(self, kind: str, count: int, timeout: float, inst: Instrument) -> bool:
        """Wait until ``kind`` has been reported ``count`` times; False on timeout or if acquisition ends."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while self.kinds.count(kind) < count:
                if time.monotonic() > deadline or not inst.running:
                    return self.kinds.count(kind) >= count
                self._cond.wait(0.05)
            return True

    def last_at(self, kind: str) -> float:
        """:func:`time.monotonic` reading of the latest ``kind`` event."""
        return self._last_at[kind]


__all__ = ["InstrumentConformance", "simulated", "DeviceError"]
