"""The simulator: a thermometer whose temperature drifts linearly, streamed as ``!T <ms> <mK>``."""

from __future__ import annotations

from mirrorlab.core.devices import CommandError, LineSimulator


class AcmeThermometerModel(LineSimulator):
    kind = "ATHM"
    vendor = "ACME"
    model = "T-100"
    firmware = "2.1"
    serial_number = "A0042"

    def reset(self) -> None:
        super().reset()
        self.rate_hz = 10.0
        self.drift_mk_per_s = 5.0  # millikelvin per second
        self._next_ms = 0.0

    def temperature_mk(self, ms: float) -> float:
        return 293_150.0 + self.drift_mk_per_s * ms / 1000.0 + self.rng.gauss(0.0, 1.0)

    def cmd_RATE(self, args: list[str]):
        self.expect(args, 1, "RATE <Hz>")
        self.rate_hz = self.number(args[0], 1, 1000, integer=False)
        yield f"OK {self.rate_hz:g}"

    def cmd_RATE_Q(self, args: list[str]):
        yield f"OK {self.rate_hz:g}"

    def cmd_READ_Q(self, args: list[str]):
        yield f"OK {int(self.clock_ms)} {self.temperature_mk(self.clock_ms):.0f}"

    def cmd_DRIFT(self, args: list[str]):
        self.expect(args, 1, "DRIFT <mK/s>")
        self.drift_mk_per_s = self.number(args[0], -1e6, 1e6, integer=False)
        yield "OK"

    def stream_lines(self) -> list[str]:
        lines = []
        period = 1000.0 / self.rate_hz
        self._next_ms = max(self._next_ms, self.clock_ms - 100 * period)  # after a pause, do not flood
        while self._next_ms <= self.clock_ms:
            lines.append(f"!T {int(self._next_ms)} {self.temperature_mk(self._next_ms):.0f}")
            self._next_ms += period
        return lines

    def truth_lines(self) -> list[str]:
        return [f"DRIFT {self.drift_mk_per_s:g}"]

    def fault_names(self) -> tuple[str, ...]:
        return ()


__all__ = ["AcmeThermometerModel", "CommandError"]
