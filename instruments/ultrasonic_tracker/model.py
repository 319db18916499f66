"""``UltrasonicTrackerModel``: the simulated ultrasonic direction tracker (``kind = USDF``, §2).

A 12-element 40 kHz array on a two-axis servo platform (theta1 about Y, theta2 about Z, +-40 deg,
8-bit set-points). Emissions give echoes of the world's spheres (and injected reflectors) with the
array's steered directivity (:mod:`.acoustics`, :mod:`.echoes`); ``IDENT`` finds the target echo
by a double emission with a random period; ``MEAS?`` reads the four deflected pressures at that
time; ``TRACK ON`` runs the search (4.4)-(4.8) autonomously, one cycle after another.

The scene is a :class:`TrackingWorld` (constructor argument, shareable); the tracker stands at
``mount`` looking along ``forward`` at rest (default: the world origin, looking along +z), with
``y`` up. Time advances with the simulator clock (:meth:`advance`).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np
from mirrorlab.core.devices import CommandError, Delay, LineSimulator
from mirrorlab.instruments.virtual_lab.simulators import SeededNoise, fault_usage
from mirrorlab.instruments.virtual_lab.world import InWorld, Path, SharedWorld, Sphere, TrackingWorld

from .acoustics import PITCH, speed_of_sound, wavenumber
from .echoes import common_arrivals, echo_arrivals, gated_pressure
from .search import RANGE, quantise, search_step

Lines = Iterator["str | Delay"]
GAIN_COUNTS = 700.0              # ADC counts for pressure 1 (the 130 mm sphere on axis at 1 m)
TARGET_RADIUS = 65.0             # the thesis's 130 mm resin-coated paper sphere, mm
DIRECT = (0.3e-3, 900.0)         # direct wave S1: arrival (s) and counts
DIRECT_GATE = 1.0e-3             # arrivals before this are the direct wave, s
DETECT = 12.0                    # an arrival is seen above this many counts
TOLERANCE = 0.1e-3               # "common" arrivals of two emissions agree within this, s
GATE_WIDTH = 0.5e-3              # peak-hold gate half-width (a 20-cycle burst), s
PULSE_GAP = 0.5e-3               # the two closely spaced pulses of one direction, s
COMPUTE_S = 0.014                # gradient, step and output: with these, one cycle at 1.3 m takes 80 ms, s
LOST_CYCLES = 3
KH_DEFAULT = 200.0               # step law h = min(h0, Kh / S): counts x deg; calibrated (see experiments)
PSI_QUANTUM = math.radians(1.44)   # 0.1 us of the 10 MHz counter chain at 40 kHz
PSI_STEPS = 62                     # quanta in the 0...90 deg of PSI: 89.28 deg at most
TEMP_RANGE = (-50, 100)          # SIM:FAULT TEMP, degC: air the tracker can work in
REVERB_S = (9.7e-3, 13.1e-3, 16.9e-3, 22.3e-3, 27.8e-3)   # room echoes for LEFTOVER, s


@dataclass(frozen=True)
class Servo:
    """Second-order position loop of the platform axes (not in the thesis).

    ``natural_hz`` is calibrated (6 Hz rather than the spec's suggested 3 Hz) so that, with the
    search, a target circling at 1.3 m is lost at 27.5 deg/s (0.48 rad/s, §2.6); damping and
    slew are the spec's §2.7 defaults.
    """

    natural_hz: float = 6.0
    damping: float = 0.7
    slew: float = math.radians(60.0)
    gains: tuple[float, float] = (1.0, 0.8)    # the two loops' different gains (jitter at rest, §2.6)


DEFAULT_SERVO = Servo()

FAULTS: dict[str, tuple[str, ...]] = {
    "BGECHO": ("az_deg", "el_deg", "range_mm", "amp"),
    "LEFTOVER": ("amp", "decay_ms"),
    "FLAT": ("normal_az_deg", "normal_el_deg"),
    "SIDELOBE": ("gain",),
    "TEMP": ("celsius",),
    "NOISE": ("sigma",),
    "SERVOGAIN": ("axis", "factor"),
    "WIND": ("m_per_s",),
}


class UltrasonicTrackerModel(InWorld, SeededNoise, LineSimulator):
    """Simulated USDF tracker.

    Parameters
    ----------
    world
        The scene (default: the 130 mm sphere 1.3 m ahead), or a :class:`SharedWorld` that other
        simulators see too (then this simulator runs on the world's clock).
    seed
        Seed of the simulator's random generator.
    servo
        Platform servo; ``None`` = an ideal platform that is always at its set-point (the
        thesis's "excluding servo motion" bound).
    mount, forward
        Tracker position (mm) and its axis at rest (unit vector) in the world; ``y`` is up.
    """

    kind = "USDF"
    model = "USDF-12"
    firmware = "1.0"
    serial_number = "SIM0002"
    load_usage = "SIM:LOAD STILL <th1> <th2> <range> | CIRCLE <th1> <rate> <range> <start_s> | LINE <x y z vx vy vz>"

    def __init__(self, world: TrackingWorld | SharedWorld | None = None, seed: int = 0,
                 servo: Servo | None = DEFAULT_SERVO, mount: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 forward: tuple[float, float, float] = (0.0, 0.0, 1.0)) -> None:
        self.servo = servo
        self.mount = np.asarray(mount, dtype=float)
        x = np.asarray(forward, dtype=float) / np.linalg.norm(forward)
        y = np.array([0.0, 1.0, 0.0])
        self.frame = np.stack([x, y, np.cross(x, y)])     # rows: tracker axes in world coordinates
        self.theta = np.zeros(2)
        self.rate = np.zeros(2)
        super().__init__(world, lambda: TrackingWorld((Sphere(Path((0.0, 0.0, 1300.0)), radius=TARGET_RADIUS),)), seed)
        self.physics_s = self.clock_ms / 1000.0

    # -- state -------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Power-on electronics; the platform keeps its angles, its set-point becomes them."""
        super().reset()
        self.setpoint = quantise(getattr(self, "theta", np.zeros(2)))
        self.psi = round(math.radians(45.0) / PSI_QUANTUM) * PSI_QUANTUM
        self.beam = "0"
        self.h0, self.kh = math.radians(2.5), math.radians(KH_DEFAULT)
        self.rand_s = (0.012, 0.018)
        self.tracking = False
        self.identified: float | None = None
        self.missed = 0
        self.last_pressure = 0.0
        self.track_flags: set[str] = set()
        self.pending: list[tuple[float, str]] = []     # (due s, line)
        self.previous_emission = (-1.0, 1.0)     # (time, period) of the last emission, for left-overs
        self.next_cycle_s = 0.0

    @property
    def state(self) -> str:
        return "TRACK" if self.tracking else "IDLE"

    @property
    def streaming(self) -> bool:
        return self._stream_on or bool(self.pending)

    @streaming.setter
    def streaming(self, on: bool) -> None:
        self._stream_on = on

    def stream_lines(self) -> list[str]:
        """Stream lines due by now (a cycle's ``!TRK`` line is due when the cycle ends)."""
        now = self.clock_ms / 1000.0
        due = [line for t, line in self.pending if t <= now + 1e-9]
        self.pending = [(t, line) for t, line in self.pending if t > now + 1e-9]
        return due

    def next_due_ms(self) -> float | None:
        """The next ``!TRK`` line or, while tracking, the next cycle's start (device ms)."""
        times = [t for t, _ in self.pending] + ([self.next_cycle_s] if self.tracking else [])
        return 1000.0 * min(times) if times else None

    def fault_names(self) -> tuple[str, ...]:
        return tuple(FAULTS)

    def cmd_SIM_FAULT(self, args: list[str]) -> Lines:
        if args and args[0].upper() in FAULTS:
            name = args[0].upper()
            names = FAULTS[name]
            if len(args) - 1 != len(names):
                raise CommandError(*fault_usage(name, names))
            for text, what in zip(args[1:], names):
                value = self.number(text, -1e6, 1e6, integer=what == "axis")
                if what == "axis" and value not in (1, 2):
                    raise CommandError("E03", "SERVOGAIN axis must be 1 or 2")
                if what in ("range_mm", "amp", "decay_ms", "sigma", "factor", "m_per_s", "gain") and value < 0:
                    raise CommandError("E03", f"{name} {what} must not be negative")
                if what == "celsius" and not TEMP_RANGE[0] <= value <= TEMP_RANGE[1]:
                    raise CommandError("E03", f"TEMP {text} outside {TEMP_RANGE[0]}..{TEMP_RANGE[1]} degC (air)")
            if name == "SERVOGAIN":
                self.faults[f"SERVOGAIN {int(args[1])}"] = args[2:]
                yield "OK"
                return
        yield from super().cmd_SIM_FAULT(args)

    # -- physics -----------------------------------------------------------------------------------
    @property
    def celsius(self) -> float:
        return self.fault_value("TEMP", 0, 20.6)         # 344 m/s, the thesis's value

    def _servo_gain(self, axis: int) -> float:
        return self.fault_value(f"SERVOGAIN {axis + 1}", 0, 1.0)

    def _integrate(self, until_s: float) -> None:
        """Move the platform toward its set-point up to physics time ``until_s``."""
        if self.servo is None:
            self.theta, self.rate, self.physics_s = self.setpoint.copy(), np.zeros(2), max(self.physics_s, until_s)
            return
        s = self.servo
        wn = 2 * math.pi * s.natural_hz
        # Python floats in the 1 ms loop: numpy scalar calls here cost most of a cycle's CPU time
        gains = [s.gains[i] * self._servo_gain(i) * wn**2 for i in range(2)]
        setpoint, theta, rate = self.setpoint.tolist(), self.theta.tolist(), self.rate.tolist()
        t = self.physics_s
        while t < until_s:
            h = min(1e-3, until_s - t)
            for i in range(2):
                acc = gains[i] * (setpoint[i] - theta[i]) - 2 * s.damping * wn * rate[i]
                rate[i] = min(max(rate[i] + h * acc, -s.slew), s.slew)
                theta[i] += h * rate[i]
            t += h
        self.theta, self.rate, self.physics_s = np.array(theta), np.array(rate), t

    def advance(self, seconds: float) -> None:
        """Advance the clock (a shared world's: up to its time): the platform moves, and in TRACK mode
        search cycles run as they fall due."""
        super().advance(seconds)
        now = self.clock_ms / 1000.0
        while self.tracking and self.next_cycle_s <= now:
            self.send_due_lines()   # the previous cycle's line leaves before this one is computed
            self.next_cycle_s += self._cycle(self.next_cycle_s)
        self._integrate(now)

    def _scatterers(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Directions (tracker frame), ranges (mm) and echo strengths of every reflector at ``t``."""
        dirs, ranges, amps = [], [], []
        flat = self.faults.get("FLAT")
        for k, sphere in enumerate(self.world.spheres):
            v = self.frame @ (sphere.path.position(t) - self.mount)
            r = float(np.linalg.norm(v))
            if r <= sphere.radius:
                continue   # a sphere that reaches the array has no direction to echo from
            amp = sphere.radius / TARGET_RADIUS
            if k == 0 and flat:                      # a flat target echoes only near specular geometry
                az, el = math.radians(float(flat[0])), math.radians(float(flat[1]))
                normal = np.array([math.cos(el) * math.cos(az), math.sin(el), -math.cos(el) * math.sin(az)])
                off = math.acos(float(np.clip(np.dot(-v / r, normal), -1.0, 1.0)))
                amp *= 4.0 * math.exp(-0.5 * (off / math.radians(5.0)) ** 2)
            dirs.append(v / r)
            ranges.append(r)
            amps.append(amp)
        bg = self.faults.get("BGECHO")
        if bg:
            az, el, r, amp = (float(x) for x in bg)
            a, e = math.radians(az), math.radians(el)
            dirs.append(np.array([math.cos(e) * math.cos(a), math.sin(e), -math.cos(e) * math.sin(a)]))
            ranges.append(r)
            amps.append(amp)
        return np.array(dirs).reshape(-1, 3), np.array(ranges), np.array(amps)

    def _emission(self, t: float, beam: str, period: float) -> tuple[np.ndarray, np.ndarray]:
        """Arrivals (s after emission) and counts heard in the window ``period`` after an emission at ``t``."""
        self._integrate(t)
        dirs, ranges, amps = self._scatterers(t)
        times, pressure = echo_arrivals(dirs, ranges, amps, self.theta, beam, self.psi, self.celsius)
        counts = GAIN_COUNTS * pressure
        sidelobe = self.fault_value("SIDELOBE")
        if sidelobe and beam != "0":              # non-planar sources: excess sidelobes grow with deflection
            counts = counts + sidelobe * (self.psi / (math.pi / 2)) * GAIN_COUNTS * amps / (ranges / 1000.0) ** 2 * 0.1
        wind = self.fault_value("WIND")
        if wind:
            c = speed_of_sound(self.celsius) / 1000.0
            times = times + self.np_rng.normal(0.0, 1.0, times.shape) * 2 * ranges / 1000.0 * wind / c**2
        keep = times < period
        times, counts = list(times[keep]), list(counts[keep])
        leftover = self.faults.get("LEFTOVER")
        if leftover:                              # room echoes of the previous emission still arriving
            amp, decay = float(leftover[0]), float(leftover[1]) / 1000.0
            since = t - self.previous_emission[0]
            for d in REVERB_S:
                late = d - since
                if 0 < late < period:
                    times.append(late)
                    counts.append(GAIN_COUNTS * amp * math.exp(-d / decay))
        times.append(DIRECT[0])
        counts.append(DIRECT[1])
        self.previous_emission = (t, period)
        noisy = np.array(counts) + self.np_rng.normal(0.0, self.fault_value("NOISE", 0, 3.0), len(counts))
        adc = np.clip(np.round(noisy), 0, 1023)
        order = np.argsort(times)
        t_arr, c_arr = np.array(times)[order], adc[order]
        seen = c_arr > DETECT
        return t_arr[seen], c_arr[seen]

    def _period(self) -> float:
        return float(self.np_rng.uniform(*self.rand_s))

    def _identify(self, t: float) -> tuple[float | None, float, bool]:
        """Double emission from ``t``: (identified arrival s or None, time used s, any arrival seen)."""
        p1, p2 = self._period(), self._period()
        first, _ = self._emission(t, "0", p1)
        second, _ = self._emission(t + p1, "0", p2)
        late = [a for a in (first, second) if (a > DIRECT_GATE).any()]
        common = common_arrivals(first[first > DIRECT_GATE], second[second > DIRECT_GATE], TOLERANCE)
        return (float(common[0]) if common.size else None), p1 + p2, bool(late)

    def _measure(self, t: float, gate: float) -> tuple[np.ndarray, float]:
        """The four deflected double-pulse pressures (counts) at ``gate`` from ``t``; (pressures, time used)."""
        window = gate + GATE_WIDTH
        readings, used = [], 0.0
        for beam in "ABCD":
            pair = []
            for _ in range(2):
                times, counts = self._emission(t + used, beam, window)
                pair.append(gated_pressure(times, counts, gate, GATE_WIDTH))
                used += PULSE_GAP
            used += window
            readings.append(float(np.mean(pair)))
        return np.array(readings), used

    def _cycle(self, t: float) -> float:
        """One autonomous search cycle from ``t``: identify, measure, step. Returns its duration, s."""
        gate, used, _ = self._identify(t)
        flags: set[str] = set()
        if gate is None:
            self.missed += 1
            self.last_pressure = 0.0
            used += COMPUTE_S
        else:
            self.missed, self.identified = 0, gate
            pressures, meas = self._measure(t + used, gate)
            used += meas + COMPUTE_S
            self._integrate(t + used)
            new, h = search_step(quantise(self.theta), tuple(pressures), self.h0, self.kh)
            if np.allclose(new, self.setpoint):
                flags.add("Q")
            self.setpoint = new
            self.last_pressure = float(pressures.mean())
            if np.any(np.abs(new) >= RANGE):
                flags.add("E")
        if self.missed >= LOST_CYCLES:
            flags.add("L")
        self.track_flags = flags
        if self._stream_on:
            th = np.degrees(self.theta)
            self.pending.append((t + used, f"!TRK {int(round((t + used) * 1000))} {self.fixed(th[0], 3)} {self.fixed(th[1], 3)} "
                                           f"{self.last_pressure:.1f} {''.join(sorted(flags)) or '-'}"))
        return used

    # -- commands (§2.8) ---------------------------------------------------------------------------
    def _require_idle(self) -> None:
        if self.tracking:
            raise CommandError("E04", "busy: tracking; send TRACK OFF first")

    def cmd_STAT_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "STAT?")
        names = {"L": "LOST", "E": "ENDSTOP", "Q": "QUIET"}
        flags = sorted(self.flags | {names[f] for f in self.track_flags})
        yield f"OK {self.state} {','.join(flags) or '-'}"

    def cmd_AIM(self, args: list[str]) -> Lines:
        self.expect(args, 2, "AIM <th1 deg> <th2 deg>")
        self._require_idle()
        values = [self.number(a, -1e6, 1e6, integer=False) for a in args]
        if any(abs(v) > 40.0 for v in values):
            raise CommandError("E03", f"set-point beyond +-40 deg: {args[0]} {args[1]}")
        self.setpoint = quantise(np.radians(values))
        yield from self.cmd_AIM_Q([])

    def cmd_AIM_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "AIM?")
        th = np.degrees(self.setpoint)
        yield f"OK {self.fixed(th[0], 4)} {self.fixed(th[1], 4)}"

    def cmd_PSI(self, args: list[str]) -> Lines:
        self.expect(args, 1, "PSI <deg>")
        deg = self.number(args[0], 0.0, 90.0, integer=False)
        # the nearest quantum, but never beyond the 90 deg the command allows
        self.psi = min(round(math.radians(deg) / PSI_QUANTUM), PSI_STEPS) * PSI_QUANTUM
        delta = math.asin(min(1.0, 2 * self.psi / (math.sqrt(3.0) * wavenumber(self.celsius) * PITCH)))
        yield f"OK {math.degrees(self.psi):.2f} {math.degrees(delta):.2f}"

    def cmd_BEAM(self, args: list[str]) -> Lines:
        self.beam = self.keyword(args, "BEAM 0|A|B|C|D")
        yield "OK"

    def _now(self) -> float:
        return self.clock_ms / 1000.0

    def cmd_EMIT(self, args: list[str]) -> Lines:
        self.expect(args, 0, "EMIT")
        self._require_idle()
        period = self._period()
        times, counts = self._emission(self._now(), self.beam, period)
        yield Delay(period)
        for t, c in zip(times, counts):
            yield f"ECHO {t * 1000:.2f} {int(c)}"
        yield "OK"

    def cmd_IDENT(self, args: list[str]) -> Lines:
        self.expect(args, 0, "IDENT")
        self._require_idle()
        gate, used, seen = self._identify(self._now())
        yield Delay(used)
        if gate is None:
            self.identified = None
            raise CommandError("E21", "ambiguous: no arrival common to both emissions") if seen else \
                CommandError("E20", "no echo")
        self.identified = gate
        yield f"OK {gate * 1000:.2f}"

    def cmd_MEAS_Q(self, args: list[str]) -> Lines:
        self.expect(args, 0, "MEAS?")
        self._require_idle()
        if self.identified is None:
            raise CommandError("E20", "no echo identified; send IDENT first")
        pressures, used = self._measure(self._now(), self.identified)
        yield Delay(used)
        yield f"OK {' '.join(f'{p:.1f}' for p in pressures)} {self.identified * 1000:.2f}"

    def cmd_STEP(self, args: list[str]) -> Lines:
        self.expect(args, 2, "STEP <h0 deg> <Kh>")
        self.h0 = math.radians(self.number(args[0], 0.0, 40.0, integer=False))
        self.kh = math.radians(self.number(args[1], 0.0, 1e6, integer=False))
        yield "OK"

    def cmd_RAND(self, args: list[str]) -> Lines:
        self.expect(args, 2, "RAND <min_ms> <max_ms>")
        lo, hi = (self.number(a, 1.0, 1000.0, integer=False) for a in args)
        if lo > hi:
            raise CommandError("E03", f"RAND min {lo:g} above max {hi:g}")
        self.rand_s = (lo / 1000.0, hi / 1000.0)
        yield "OK"

    def cmd_STREAM(self, args: list[str]) -> Lines:
        """``STREAM ON|OFF``; off, the line of the cycle in progress is not sent either (no line after the ``OK``)."""
        yield from super().cmd_STREAM(args)
        if not self._stream_on:
            self.pending = []

    def cmd_TRACK(self, args: list[str]) -> Lines:
        on = self.keyword(args, "TRACK ON|OFF") == "ON"
        if on and not self.tracking:
            self.next_cycle_s = self._now()
            self.missed = 0
        self.tracking = on
        if not on:
            self.track_flags = set()
        yield "OK"

    # -- scenarios and truth -------------------------------------------------------------------------
    def scenario(self, kind: str, values: list[float], t0: float) -> Path | None:
        """``SIM:LOAD STILL <th1 deg> <th2 deg> <range mm>`` | ``CIRCLE <th1 deg> <rate deg/s> <range mm> <start s>``
        | ``LINE <x> <y> <z> <vx> <vy> <vz>`` (tracker frame, mm, mm/s): replace the target."""
        to_world = self.frame.T
        if kind == "STILL" and len(values) == 3:
            d = np.array([math.cos(math.radians(values[1])) * math.cos(math.radians(values[0])),
                          math.sin(math.radians(values[1])),
                          -math.cos(math.radians(values[1])) * math.sin(math.radians(values[0]))])
            return Path(tuple(self.mount + to_world @ (values[2] * d)))
        if kind == "CIRCLE" and len(values) == 4:
            # about the vertical through the tracker; world phase measured from +z toward +x
            fwd = self.frame[0]
            az0 = math.atan2(fwd[0], fwd[2]) + math.radians(values[0])
            return Path(tuple(self.mount), radius=values[2], rate=math.radians(values[1]), phase=az0,
                        start_s=t0 + values[3])
        if kind == "LINE" and len(values) == 6:
            return Path(tuple(self.mount + to_world @ np.array(values[:3])), tuple(to_world @ np.array(values[3:])),
                        start_s=t0)
        return None

    def target_angles(self, t: float) -> tuple[float, float]:
        """Platform angles ``(theta1, theta2)`` that point the array axis at the target at ``t``, rad."""
        v = self.frame @ (self.world.target_position(t) - self.mount)
        return math.atan2(-v[2], v[0]), math.atan2(v[1], math.hypot(v[0], v[2]))

    def truth_lines(self) -> list[str]:
        """``TIME <ms>``, ``TARGET <th1> <th2> <range mm>`` (deg), ``PLATFORM <th1> <th2>`` (deg, actual),
        ``ERROR <deg>`` (angle between the array axis and the target), ``SOUND <m/s>`` and ``FAULT`` lines."""
        t = self._now()
        self._integrate(t)
        t1, t2 = self.target_angles(t)
        v = self.frame @ (self.world.target_position(t) - self.mount)
        u0 = np.array([math.cos(self.theta[0]) * math.cos(self.theta[1]), math.sin(self.theta[1]),
                       -math.sin(self.theta[0]) * math.cos(self.theta[1])])
        error = math.degrees(math.acos(float(np.clip(np.dot(u0, v / max(float(np.linalg.norm(v)), 1e-9)), -1, 1))))
        th = np.degrees(self.theta)
        return [f"TIME {int(self.clock_ms)}",
                f"TARGET {self.fixed(math.degrees(t1), 4)} {self.fixed(math.degrees(t2), 4)} {np.linalg.norm(v):.1f}",
                f"PLATFORM {self.fixed(th[0], 4)} {self.fixed(th[1], 4)}", f"ERROR {error:.4f}",
                f"SOUND {speed_of_sound(self.celsius) / 1000:.2f}", *self.fault_lines()]
