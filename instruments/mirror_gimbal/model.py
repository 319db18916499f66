"""``MirrorGimbalModel``: the simulated active mirror (``kind = MGIM``, ``instruments.md`` §4).

Two axes (``H`` about the vertical, ``V`` about the horizontal), each a DC motor driving the 1 m
mirror and, through 1:2 gearing, a line-sensor detector (:mod:`.dynamics`). Every detector scan
(``512 / clock`` s, 78.8 ms at 6.5 kHz) each axis samples its detector and, by mode, sets its DAC:
``TRACK`` by (4.11)-(4.12), ``POS`` by a position loop on the shaft sensor, ``HOLD`` brakes,
``OFF`` gives 0 V. The scene is a :class:`TrackingWorld` (constructor argument, so one world can be
shared by several simulators). The detectors answer OLDT commands as ``H:...`` / ``V:...``.

Time: physics advances with the simulator clock (:meth:`advance`), in whole scans.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np
from mirrorlab.core.devices import CommandError, LineSimulator
from mirrorlab.instruments.virtual_lab.line_sensor.detector import OpticalDetector
from mirrorlab.instruments.virtual_lab.line_sensor.scanned_lines import ScannedLines
from mirrorlab.instruments.virtual_lab.line_sensor.view import (
    OPTICAL_FAULTS,
    detector_projection,
    optical_faults,
)
from mirrorlab.instruments.virtual_lab.simulators import fault_usage
from mirrorlab.instruments.virtual_lab.world import (
    Path,
    SharedWorld,
    TrackingWorld,
    image_in_mirror,
    mirror_normal,
)

from .dynamics import DAC_ZERO, AxisParams, AxisState, control_dac, dac_voltage, integrate_axis

Lines = Iterator[str]
AXES = ("H", "V")
MODES = ("OFF", "TRACK", "HOLD", "POS")
LOST_SAMPLES = 3                 # E40 after this many samples without a valid mark while tracking
STALL_S = 2.0                    # E42 after the drive is saturated this long with the mirror still
STALL_RATE = math.radians(0.1)   # "still": below 0.1 deg/s
POS_GAIN = 280.0                 # POS mode: volts per rad of mirror error (type-1 loop, K dt ~ 0.6)
SOFT_LIMIT = math.radians(30.0)  # default LIMIT, mirror angle

#: name -> (argument names, whether the first argument is an axis)
FAULTS: dict[str, tuple[tuple[str, ...], bool]] = {
    "BACKLASH": (("axis", "deg"), True),
    "TORQUE": (("axis", "factor"), True),
    "INERTIA": (("axis", "factor"), True),
    "COMPLIANCE": (("axis", "Nm/rad"), True),
    "GEAR": (("axis", "ratio_error"), True),
    "PARALLAX": (("mm",), False),
    **{name: (args, False) for name, args in OPTICAL_FAULTS.items()},
}


@dataclass
class Axis:
    """One axis: mechanics, mode, loop settings and its detector."""

    name: str
    params: AxisParams = field(default_factory=AxisParams)
    state: AxisState = field(default_factory=AxisState)
    mode: str = "OFF"
    setpoint: float = 0.0        # POS target, rad of mirror angle
    gain: float = 1.0
    deadband: float = 0.0
    limits: tuple[float, float] = (-SOFT_LIMIT, SOFT_LIMIT)
    dac: float = DAC_ZERO
    k: float | None = None       # last valid detector position
    missed: int = 0              # consecutive samples without a mark (TRACK)
    saturated_s: float = 0.0
    detector: OpticalDetector = field(default_factory=OpticalDetector)


class MirrorGimbalModel(ScannedLines, LineSimulator):
    """Simulated MGIM active mirror.

    Parameters
    ----------
    world
        The scene the detectors see (both axes start turned onto its target); default: a white
        250 mm ball 3 m in front, on the camera direction. A :class:`SharedWorld` is seen by other
        simulators too (then this simulator runs on the world's clock and logs the mirror's angles
        there, for the world's truth).
    seed
        Seed of the simulator's random generator.
    params
        Mechanical parameters of both axes (calibrated defaults).
    """

    kind = "MGIM"
    model = "MGIM-1M"
    firmware = "1.0"
    serial_number = "SIM0003"
    load_usage = ("SIM:LOAD STILL <h> <v> <range> | CIRCLE <h0> <rate> <range> <start_s> | "
                  "LINE <x> <y> <z> <vx> <vy> <vz>")

    def __init__(self, world: TrackingWorld | SharedWorld | None = None, seed: int = 0,
                 params: AxisParams | None = None) -> None:
        self.base_params = params or AxisParams()
        self.axes = {a: Axis(a, self.base_params, detector=OpticalDetector(f"{a}:M")) for a in AXES}
        self.pending: list[str] = []
        self._stream_on = False
        super().__init__(world, TrackingWorld, seed)
        self.next_sample_ms = self.clock_ms
        self.pose_on_target()

    def pose_on_target(self) -> None:
        """Turn both axes (mirror and detector) onto the target as it is now: the operator's aiming."""
        for name, angle in zip(AXES, self.world.target_angles(self.clock_ms / 1000.0)):
            axis = self.axes[name]
            mirror = angle / axis.params.detector_ratio
            axis.state = AxisState(gear=mirror, mirror=mirror, detector_shaft=mirror)

    # -- state -------------------------------------------------------------------------------------
    def reset(self) -> None:
        """Power-on electronics: both axes OFF, loop settings default; the mirror stays where it is."""
        super().reset()
        for axis in getattr(self, "axes", {}).values():
            axis.mode, axis.gain, axis.deadband = "OFF", 1.0, 0.0
            axis.limits = (-SOFT_LIMIT, SOFT_LIMIT)
            axis.dac, axis.k, axis.missed, axis.saturated_s = DAC_ZERO, None, 0, 0.0
            axis.state.braked = False
            axis.detector.reset()
        self.pending = []

    @property
    def streaming(self) -> bool:
        """Whether the server should collect stream lines (own stream, a detector's, or a fault line)."""
        return self._stream_on or bool(self.pending) or any(a.detector.streaming for a in self.axes.values())

    @streaming.setter
    def streaming(self, on: bool) -> None:
        self._stream_on = on

    @property
    def state(self) -> str:
        modes = {a.mode for a in self.axes.values()}
        return "TRACK" if "TRACK" in modes else ("MOVING" if "POS" in modes else "IDLE")

    # -- faults ------------------------------------------------------------------------------------
    def fault_names(self) -> tuple[str, ...]:
        return tuple(FAULTS)

    def cmd_SIM_FAULT(self, args: list[str]) -> Lines:
        if args and args[0].upper() in FAULTS and args[0].upper() not in OPTICAL_FAULTS:  # optical: ScannedLines
            name = args[0].upper()
            names, per_axis = FAULTS[name]
            if len(args) - 1 != len(names):
                raise CommandError(*fault_usage(name, names))
            values = args[1:]
            if per_axis:
                values = [self._axis_name(values[0]), *values[1:]]
            for text, what in zip(values[1:] if per_axis else values, names[1:] if per_axis else names):
                self.number(text, -1e6, 1e6, integer=False)
                if what in ("factor", "n", "ms", "m", "px", "deg") and float(text) < 0:
                    raise CommandError("E03", f"{name} {what} must not be negative")
            key = f"{name} {values[0]}" if per_axis else name
            self.faults[key] = values[1:] if per_axis else values
            self._apply_mechanical_faults()
            yield "OK"
            return
        yield from super().cmd_SIM_FAULT(args)
        self._apply_mechanical_faults()

    def _axis_fault(self, name: str, axis: str, default: float) -> float:
        return self.fault_value(f"{name} {axis}", 0, default)

    def _apply_mechanical_faults(self) -> None:
        for a, axis in self.axes.items():
            p = self.base_params.scaled(self._axis_fault("TORQUE", a, 1.0), self._axis_fault("INERTIA", a, 1.0))
            p = replace(p, backlash=math.radians(self._axis_fault("BACKLASH", a, math.degrees(p.backlash))),
                        detector_backlash=math.radians(self._axis_fault("BACKLASH", a,
                                                                        math.degrees(p.detector_backlash))),
                        stiffness=self._axis_fault("COMPLIANCE", a, p.stiffness),
                        detector_ratio=p.detector_ratio * (1.0 + self._axis_fault("GEAR", a, 0.0)))
            axis.params = p

    # -- simulation --------------------------------------------------------------------------------
    @property
    def period_s(self) -> float:
        """The loop period: one detector scan (both detectors share the clock), s."""
        return self.axes["H"].detector.period_s

    def advance(self, seconds: float) -> None:
        """Advance the clock (a shared world's: up to its time); run every detector scan and control
        step that falls due."""
        super().advance(seconds)
        while self.next_sample_ms <= self.clock_ms:
            t = self.next_sample_ms / 1000.0
            period = self.scan_period(self.period_s)
            self.scene.note_mirror(t, self.axes["H"].state.mirror, self.axes["V"].state.mirror)
            for axis in self.axes.values():
                self._sample_axis(axis, t)
                self._drive_axis(axis, period)
            self.next_sample_ms += period * 1000.0

    def detector_signal(self, axis: Axis, t: float) -> np.ndarray:
        """The video signal (counts) of ``axis``'s detector at world time ``t`` (s)."""
        faults = optical_faults(self.faults)
        proj = detector_projection(self.world, t, axis.name, axis.state.detector_angle(axis.params), faults,
                                   self.fault_value("PARALLAX"))
        return self.scan_signal(proj, axis.detector.clock_hz, faults)

    def _sample_axis(self, axis: Axis, t: float) -> None:
        ms = int(round(t * 1000.0))
        mark = axis.detector.sample(self.detector_signal(axis, t), ms)
        valid = mark.valid or mark.error == ("E32", "saturated")
        line = axis.detector.stream_line()
        if line:
            self.pending.append(line)
        if axis.mode == "TRACK":
            if valid:
                axis.k, axis.missed = mark.m, 0
                axis.dac = control_dac(mark.m, axis.gain)
            else:
                axis.missed += 1
                if axis.missed >= LOST_SAMPLES:
                    self._set_mode(axis, "HOLD")
                    self.flags.add(f"LOST_{axis.name}")
                    self.pending.append(self.raise_fault("E40", f"lost: axis {axis.name} saw no mark for "
                                                                f"{LOST_SAMPLES} samples; holding"))
        elif axis.mode == "POS":
            volts = np.clip(POS_GAIN * (axis.setpoint - axis.state.mirror), -axis.params.v_max, axis.params.v_max)
            axis.dac = float(np.clip(math.floor(DAC_ZERO + volts / axis.params.v_max * DAC_ZERO + 0.5), 0, 255))
        if self._stream_on:
            k = f"{mark.m:.1f}" if valid else "-"
            e = f"{mark.m - 255.0:.1f}" if valid else "-"
            self.pending.append(f"!G {ms} {axis.name} {k} {e} {self.fixed(math.degrees(axis.state.mirror), 3)}")

    def _drive_axis(self, axis: Axis, period: float) -> None:
        if axis.mode in ("TRACK", "POS"):
            volts = dac_voltage(axis.dac, axis.params.v_max, axis.deadband)
        else:
            volts = 0.0
        before = axis.state.mirror
        axis.state, limited = integrate_axis(axis.state, volts, axis.params, period)
        stuck = abs(axis.state.mirror_rate) < STALL_RATE
        axis.saturated_s = axis.saturated_s + period if limited and volts and stuck else 0.0
        if axis.saturated_s >= STALL_S and f"STALL_{axis.name}" not in self.flags:
            self.flags.add(f"STALL_{axis.name}")
            self.pending.append(self.raise_fault("E42", f"stalled: axis {axis.name} drive saturated for "
                                                        f"{STALL_S:g} s"))
        lo, hi = axis.limits
        m = axis.state.mirror
        if axis.mode == "TRACK" and not lo <= m <= hi:
            self._set_mode(axis, "HOLD")
            self.flags.add(f"LIMIT_{axis.name}")
            self.pending.append(self.raise_fault("E41", f"soft limit: axis {axis.name} stopped at "
                                                        f"{math.degrees(m):.2f} deg"))
        if abs(m) >= axis.params.end_stop and abs(before) < axis.params.end_stop:
            self.flags.add(f"ENDSTOP_{axis.name}")
            self.pending.append(self.raise_fault("E06", f"end stop: axis {axis.name} at {math.degrees(m):.1f} deg"))

    def _set_mode(self, axis: Axis, mode: str) -> None:
        axis.mode = mode
        axis.state.braked = mode == "HOLD"
        if mode == "TRACK":
            axis.missed = 0
            self.flags.discard(f"LOST_{axis.name}")
            self.flags.discard(f"LIMIT_{axis.name}")
        axis.saturated_s = 0.0
        self.flags.discard(f"STALL_{axis.name}")

    # -- commands (§4.5) ---------------------------------------------------------------------------
    def handle(self, line: str) -> Lines:
        words = self.words(line)
        head = words[0].upper() if words else ""
        if len(head) > 2 and head[1] == ":" and head[0] in "HV" and not head.startswith("SIM"):
            detector = self.axes[head[0]].detector
            return self._detector_command(detector, [head[2:], *words[1:]])
        return super().handle(line)

    def _detector_command(self, detector: OpticalDetector, words: list[str]) -> Lines:
        clock = detector.clock_hz
        yield from detector.handle(words)
        if detector.clock_hz != clock:                 # one clock for both sensors
            for axis in self.axes.values():
                axis.detector.clock_hz = detector.clock_hz

    def _axis_name(self, text: str) -> str:
        if text.upper() not in AXES:
            raise CommandError("E02", f"axis must be H or V, not {text}")
        return text.upper()

    def _axis(self, text: str) -> Axis:
        return self.axes[self._axis_name(text)]

    def cmd_MODE(self, args: list[str]) -> Lines:
        self.expect(args, 2, "MODE <H|V> OFF|TRACK|HOLD|POS")
        axis = self._axis(args[0])
        mode = args[1].upper()
        if mode not in MODES:
            raise CommandError("E02", "usage: MODE <H|V> OFF|TRACK|HOLD|POS")
        if mode == "POS":
            axis.setpoint = axis.state.mirror
        self._set_mode(axis, mode)
        yield "OK"

    def cmd_POS(self, args: list[str]) -> Lines:
        self.expect(args, 2, "POS <H|V> <deg>")
        axis = self._axis(args[0])
        deg = self.number(args[1], -90.0, 90.0, integer=False)
        lo, hi = axis.limits
        if not lo <= math.radians(deg) <= hi:
            raise CommandError("E41", f"soft limit: {deg:g} deg outside LIMIT {math.degrees(lo):g}.."
                                      f"{math.degrees(hi):g} deg")
        axis.setpoint = math.radians(deg)
        self._set_mode(axis, "POS")
        yield f"OK {self.fixed(deg, 3)}"

    def cmd_ANG_Q(self, args: list[str]) -> Lines:
        self.expect(args, 1, "ANG? <H|V>")
        axis = self._axis(args[0])
        yield (f"OK {self.fixed(math.degrees(axis.state.mirror), 3)} "
               f"{self.fixed(math.degrees(axis.state.detector_angle(axis.params)), 3)}")

    def cmd_SENS_Q(self, args: list[str]) -> Lines:
        self.expect(args, 1, "SENS? <H|V>")
        mark = self._axis(args[0]).detector.mark
        if not mark.valid and mark.error != ("E32", "saturated"):
            raise CommandError(*mark.error)
        yield f"OK {mark.ms} {mark.m:.1f} {mark.d} {mark.threshold}"

    def cmd_GAIN(self, args: list[str]) -> Lines:
        self.expect(args, 2, "GAIN <H|V> <k>")
        self._axis(args[0]).gain = self.number(args[1], 0.0, 100.0, integer=False)
        yield "OK"

    def cmd_LIMIT(self, args: list[str]) -> Lines:
        self.expect(args, 3, "LIMIT <H|V> <min deg> <max deg>")
        axis = self._axis(args[0])
        stop = math.degrees(axis.params.end_stop)
        lo = self.number(args[1], -stop, stop, integer=False)
        hi = self.number(args[2], -stop, stop, integer=False)
        if lo >= hi:
            raise CommandError("E03", f"LIMIT min {lo:g} must be below max {hi:g}")
        axis.limits = (math.radians(lo), math.radians(hi))
        yield "OK"

    def cmd_DEADBAND(self, args: list[str]) -> Lines:
        self.expect(args, 2, "DEADBAND <H|V> <counts>")
        axis = self._axis(args[0])
        axis.deadband = self.number(args[1], 0.0, 127.5, integer=False)
        yield f"OK {axis.deadband:g}"

    # -- scenarios and truth -------------------------------------------------------------------------
    def scenario(self, kind: str, values: list[float], t0: float) -> Path | None:
        """``SIM:LOAD STILL <h deg> <v deg> <range mm>`` | ``CIRCLE <h0 deg> <rate deg/s> <range mm> <start s>``
        | ``LINE <x> <y> <z> <vx> <vy> <vz>`` (mm, mm/s): replace the target."""
        c = self.world.camera_direction
        if kind == "STILL" and len(values) == 3:
            h, v, r = math.radians(values[0]), math.radians(values[1]), values[2]
            return Path(tuple(r * mirror_normal(h, v, c)))
        if kind == "CIRCLE" and len(values) == 4:
            h0, rate, r, start = math.radians(values[0]), math.radians(values[1]), values[2], values[3]
            az0 = math.atan2(c[0], c[2]) + h0
            return Path(radius=r, rate=rate, phase=az0, start_s=t0 + start)
        if kind == "LINE" and len(values) == 6:
            return Path(tuple(values[:3]), tuple(values[3:]), start_s=t0)
        return None

    def cmd_SIM_LOAD(self, args: list[str]) -> Lines:
        """``SIM:LOAD`` (:meth:`scenario`), then the detectors are turned onto the new target."""
        replies = list(super().cmd_SIM_LOAD(args))
        self.pose_on_target()
        yield from replies

    def truth_lines(self) -> list[str]:
        """``TIME``, ``TARGET``, ``AXIS`` per axis, ``NORMAL``, ``INMIRROR`` and ``FAULT`` lines.

        ``TIME <ms>``; ``TARGET <x> <y> <z>`` (mm); ``AXIS <H|V> <target deg> <mirror deg> <detector deg>
        <mirror deg/s> <mode>`` (target = its axis angle from the camera direction; the ideal mirror
        angle is half of it); ``NORMAL <x> <y> <z>`` (unit mirror normal); ``INMIRROR <0|1>`` (the
        target's image lies inside the mirror as the camera sees it).
        """
        t = self.clock_ms / 1000.0
        w = self.world
        target = w.target_position(t)
        out = [f"TIME {int(self.clock_ms)}", "TARGET " + " ".join(self.fixed(x, 2) for x in target)]
        for name, angle in zip(AXES, w.target_angles(t)):
            a = self.axes[name]
            angles = (angle, a.state.mirror, a.state.detector_angle(a.params), a.state.mirror_rate)
            out.append(f"AXIS {name} {' '.join(self.fixed(math.degrees(x), 4) for x in angles)} {a.mode}")
        normal = mirror_normal(self.axes["H"].state.mirror, self.axes["V"].state.mirror, w.camera_direction)
        out.append("NORMAL " + " ".join(self.fixed(x, 6) for x in normal))
        inside = image_in_mirror(w.camera, target, w.mirror_centre, normal, w.mirror_size, w.spheres[0].radius)
        out.append(f"INMIRROR {int(inside)}")
        return out + self.fault_lines()
