"""Open-loop film transport: stepper, lead screw, cantilevered carrier, clamps, limit switches.

Geometry (§1.2): 4.6875 µm per half-step, 10 steps per line, 1.8 ms per step. Positions are kept in
micrometres. The carrier pointer (what the host counts, ``POS?``) is in steps; the *true* carrier
position differs from it by skipped steps (``STALL``), the random feed error (``FEEDJITTER``,
accumulating because the drive is open loop) and screw backlash (``BACKLASH``, a play operator:
the carrier follows the screw only when the screw pushes it from one side of the gap).
The film moves with the carrier only while it is clamped to the carrier.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

STEP_UM = 4.6875
STEPS_PER_LINE = 10
STEP_S = 1.8e-3
TRAVEL_STEPS = 8320              # carrier travel between the limit switches (39 mm)
CENTRE_STEPS = 4160              # CHOME: pointer $1A0 = 416 lines
HOME_SEARCH_STEPS = int(TRAVEL_STEPS * 1.1)   # LCHOME gives up after more than the full travel


class LimitHit(Exception):
    """The carrier reached a limit switch; ``steps_done`` commanded steps were executed."""

    def __init__(self, side: str, steps_done: int) -> None:
        super().__init__(f"{side} limit switch")
        self.side = side
        self.steps_done = steps_done


@dataclass
class FeedFaults:
    """Feed imperfections (the ``SIM:FAULT`` values that act on the transport)."""

    backlash_um: float = 0.0
    jitter_um: float = 0.0       # sigma of the feed error added per line (10 steps) of motion
    stall_p: float = 0.0         # probability that one step is skipped


class Carrier:
    """State of the film transport.

    Attributes
    ----------
    pointer
        Commanded carrier position, steps (meaningful after homing).
    screw_um, carrier_um
        True screw-nut and carrier positions, µm from the left limit switch.
    film_um
        Strip position under the sensor line, µm.
    film_steps
        Steps commanded while the film was clamped to the carrier (n_j of §1.4).
    clamp
        ``"BASE"`` or ``"CARRIER"``.
    """

    def __init__(self, carrier_um: float = 20000.0, film_um: float = -3000.0) -> None:
        self.pointer = 0
        self.screw_um = carrier_um
        self.carrier_um = carrier_um
        self.film_um = film_um
        self.film_steps = 0
        self.clamp = "BASE"
        self.homed = False

    @property
    def travel_um(self) -> float:
        return TRAVEL_STEPS * STEP_UM

    def at_limit(self) -> str | None:
        if self.carrier_um <= 0.0:
            return "left"
        if self.carrier_um >= self.travel_um:
            return "right"
        return None

    def move(self, steps: int, faults: FeedFaults, rng: np.random.Generator) -> None:
        """Move ``steps`` (signed) in chunks of one line, stopping at a limit switch.

        Raises
        ------
        LimitHit
            A switch closed; the pointer counts only the steps executed before it.
        """
        sign = 1 if steps > 0 else -1
        done = 0
        while done < abs(steps):
            n = min(STEPS_PER_LINE, abs(steps) - done)
            lost = int(rng.binomial(n, faults.stall_p)) if faults.stall_p > 0 else 0
            delta = sign * (n - lost) * STEP_UM
            if faults.jitter_um > 0 and n - lost > 0:
                delta += rng.normal(0.0, faults.jitter_um * np.sqrt((n - lost) / STEPS_PER_LINE))
            before = self.carrier_um
            self.screw_um += delta
            self.carrier_um = float(np.clip(self.carrier_um, self.screw_um - faults.backlash_um, self.screw_um))
            side = None
            if self.carrier_um <= 0.0 and sign < 0:
                side = "left"
            elif self.carrier_um >= self.travel_um and sign > 0:
                side = "right"
            if side is not None:
                # Stop where the switch closes; count the commanded steps up to that point.
                limit = 0.0 if side == "left" else self.travel_um
                frac = (limit - before) / (self.carrier_um - before) if self.carrier_um != before else 0.0
                executed = int(round(n * min(max(frac, 0.0), 1.0)))
                self.screw_um += limit - self.carrier_um
                self.carrier_um = limit
                self._shift(limit - before, sign * executed)
                raise LimitHit(side, done + executed)
            self._shift(self.carrier_um - before, sign * n)
            done += n

    def _shift(self, carrier_delta_um: float, commanded: int) -> None:
        """Book a carrier motion: the pointer counts commanded steps; a clamped film follows."""
        self.pointer += commanded
        if self.clamp == "CARRIER":
            self.film_um += carrier_delta_um
            self.film_steps += commanded
