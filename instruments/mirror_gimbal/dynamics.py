"""One gimbal axis: control law (4.11)-(4.12), the 8-bit DAC, the DC motor and the drive train.

Pure functions on plain numbers (``instruments.md`` §4.2, §4.4). The train of one axis:

    DAC -> PWM amplifier (voltage, current limit) -> DC motor -> reduction gear (ratio N)
        -> backlash -> torsional spring k_s -> mirror (inertia J, viscous and Coulomb friction)
        -> 1:2 gear with its own backlash -> optical detector

Angles are those of the mirror shaft (rad) unless named ``detector``; torques N m at the mirror
shaft; time s. The motor-side inertia is reflected through the gear (``rotor_inertia N^2``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

DAC_ZERO = 127.5                 # zero drive of the 8-bit DAC (never output: integers only)


@dataclass(frozen=True)
class AxisParams:
    """Physical parameters of one axis. Not in the thesis: calibrated simulator defaults (§4.4, §7).

    The defaults are calibrated so that a target that starts circling at constant range is lost
    between 13 and 17 deg/s of detector angular rate (the thesis's "about 15 deg/s").

    Attributes
    ----------
    v_max
        Amplifier output at DAC 0 / 255, V.
    resistance
        Armature resistance, ohm.
    k_t
        Torque constant = back-EMF constant, N m / A (V s / rad).
    current_limit
        Amplifier current limit, A: with ``k_t`` and ``ratio`` the motor's torque limit.
    ratio
        Reduction gear, motor turns per mirror turn.
    rotor_inertia
        Motor rotor and pinion inertia, kg m^2 (reflected: times ``ratio^2``).
    mirror_inertia
        Mirror and frame about the axis, kg m^2 (1 m^2 glass of 5 mm: about 1.0).
    viscous
        Viscous friction at the mirror, N m s / rad.
    coulomb
        Coulomb (dry) friction at the mirror, N m.
    stiffness
        Torsional stiffness between gear and mirror, N m / rad.
    damping
        Structural damping of that spring, N m s / rad.
    backlash
        Total backlash of the mirror train, rad.
    detector_backlash
        Total backlash of the 1:2 detector train, rad of mirror shaft.
    detector_ratio
        Detector turns per mirror turn (2; ``GEAR`` faults change it).
    end_stop
        Hardware end stops at +-``end_stop``, rad of mirror angle.
    """

    v_max: float = 24.0
    resistance: float = 4.0
    k_t: float = 0.12
    current_limit: float = 0.0115
    ratio: float = 300.0
    rotor_inertia: float = 1.0e-5
    mirror_inertia: float = 1.0
    viscous: float = 0.3
    coulomb: float = 0.25
    stiffness: float = 400.0
    damping: float = 4.0
    backlash: float = math.radians(0.3)
    detector_backlash: float = math.radians(0.15)
    detector_ratio: float = 2.0
    end_stop: float = math.radians(35.0)

    def scaled(self, torque: float = 1.0, inertia: float = 1.0) -> AxisParams:
        """A stronger/weaker motor (``TORQUE`` factor on the current limit) or heavier mirror."""
        return replace(self, current_limit=self.current_limit * torque,
                       mirror_inertia=self.mirror_inertia * inertia)


@dataclass
class AxisState:
    """Mechanical state of one axis (rad, rad/s at the mirror shaft)."""

    gear: float = 0.0            # gear output (motor side of backlash and spring)
    gear_rate: float = 0.0
    mirror: float = 0.0
    mirror_rate: float = 0.0
    detector_shaft: float = 0.0  # detector gear input, follows the mirror through its backlash
    braked: bool = False         # HOLD: the motor shaft is locked

    def detector_angle(self, params: AxisParams) -> float:
        """Detector rotation from the camera direction, rad."""
        return params.detector_ratio * self.detector_shaft


def control_dac(k: float, gain: float = 1.0) -> int:
    """DAC value from the detector position ``K`` (0..511): (4.11) ``E = K - 255``, (4.12) ``E' = (gE + 255)/2``.

    The DAC holds the integer ``floor(E')`` clamped to 0..255; ``gain`` = 1 is the thesis.

    Examples
    --------
    >>> control_dac(255.0), control_dac(256.0), control_dac(511.0), control_dac(0.0)
    (127, 128, 255, 0)
    >>> control_dac(265.0, gain=2.0)
    137
    """
    e = k - 255.0
    return int(np.clip(math.floor((gain * e + 255.0) / 2.0), 0, 255))


def dac_voltage(dac: float, v_max: float, deadband: float = 0.0) -> float:
    """Amplifier output for a DAC value: ``V_max (DAC - 127.5) / 127.5``; 0 V within ``deadband`` counts.

    Examples
    --------
    >>> round(dac_voltage(128, 24.0), 4), round(dac_voltage(127, 24.0), 4), dac_voltage(128, 24.0, deadband=1)
    (0.0941, -0.0941, 0.0)
    """
    offset = dac - DAC_ZERO
    if abs(offset) <= deadband:
        return 0.0
    return v_max * offset / DAC_ZERO


def play(follower: float, driver: float, width: float) -> float:
    """Backlash (play operator): the follower moves only when ``driver`` leaves the ``width`` gap.

    Examples
    --------
    >>> play(0.0, 0.1, 0.4), play(0.0, 0.5, 0.4), play(0.0, -0.5, 0.4)
    (0.0, 0.3, -0.3)
    """
    half = width / 2.0
    return min(max(follower, driver - half), driver + half)


def dead_zone(x: float, half: float) -> float:
    """``x`` minus the gap ``[-half, half]`` (0 inside): the spring's twist across backlash.

    Examples
    --------
    >>> dead_zone(0.5, 0.2), dead_zone(-0.1, 0.2), dead_zone(-0.5, 0.2)
    (0.3, 0.0, -0.3)
    """
    return x - half if x > half else (x + half if x < -half else 0.0)


def integrate_axis(state: AxisState, voltage: float, params: AxisParams, duration: float,
                   step: float = 1.0e-3) -> tuple[AxisState, bool]:
    """Advance one axis by ``duration`` s under a constant amplifier ``voltage`` (V).

    Semi-implicit Euler with ``step`` s. Returns the new state and whether the amplifier was in
    its current limit for the whole interval (drive saturated). Hitting an end stop stops the
    mirror there.

    Examples
    --------
    >>> s, _ = integrate_axis(AxisState(), 24.0, AxisParams(), 2.0)
    >>> 0.0 < s.mirror < math.radians(20.0) and s.mirror_rate > 0
    True
    """
    s = AxisState(**vars(state))
    p = params
    j_gear = p.rotor_inertia * p.ratio**2
    n_steps = max(1, int(round(duration / step)))
    h = duration / n_steps
    limited = True
    for _ in range(n_steps):
        twist = dead_zone(s.gear - s.mirror, p.backlash / 2.0)
        spring = p.stiffness * twist + (p.damping * (s.gear_rate - s.mirror_rate) if twist else 0.0)
        if s.braked:
            s.gear_rate = 0.0
        else:
            current = (voltage - p.k_t * p.ratio * s.gear_rate) / p.resistance
            if abs(current) < p.current_limit:
                limited = False
            current = min(max(current, -p.current_limit), p.current_limit)  # not np.clip: a scalar, 1000 times a second
            s.gear_rate += h * (p.ratio * p.k_t * current - spring) / j_gear
            s.gear += h * s.gear_rate
        drive = spring - p.viscous * s.mirror_rate
        if s.mirror_rate == 0.0 and abs(drive) <= p.coulomb:
            pass                                   # static friction holds the mirror
        else:
            rate = s.mirror_rate + h * (drive - p.coulomb * math.copysign(1.0, s.mirror_rate or drive)) \
                / p.mirror_inertia
            s.mirror_rate = 0.0 if s.mirror_rate and rate * s.mirror_rate < 0 else rate  # stops, not reverses
            s.mirror += h * s.mirror_rate
        if abs(s.mirror) > p.end_stop:
            s.mirror = math.copysign(p.end_stop, s.mirror)
            s.mirror_rate = 0.0
        s.detector_shaft = play(s.detector_shaft, s.mirror, p.detector_backlash)
    return s, limited
