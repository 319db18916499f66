"""The built-in controllers (adapters of :class:`mirrorlab.core.controllers.Controller`)."""

from __future__ import annotations

import math
from collections.abc import Mapping

from mirrorlab.core import Block, Controller, ControllerContext, Parameter, ParameterSet


class Follow(Controller):
    """Set an instrument's live parameter to ``gain · input + offset`` for each new input sample.

    Only the newest sample of each block counts (a loop that fell behind catches up instead of
    replaying); a change smaller than ``min_change`` is not sent. Units: the input's and the
    parameter's own (``gain`` converts one into the other, ``offset`` is in the parameter's unit).
    """

    name = "follow"
    version = "1.0.0"
    description = "drive one live parameter from a scalar stream: gain * input + offset"
    parameters = ParameterSet(
        Parameter("parameter", str, "target", help="the live parameter of the output instrument to set"),
        Parameter("gain", float, 1.0, help="output per unit of input"),
        Parameter("offset", float, 0.0, help="added to the output, in the parameter's unit"),
        Parameter("min_change", float, 0.0, bounds=(0.0, None),
                  help="smallest change worth a command, in the parameter's unit"),
    )
    inputs = {"input": "a scalar stream, e.g. a tracker's angle"}
    commands = {"output": ("target",)}
    latest_only = True

    def commanded(self) -> Mapping[str, tuple[str, ...]]:
        return {"output": (self.settings["parameter"],)}

    def setup(self, ctx: ControllerContext) -> None:
        self._last: float | None = None

    def on_block(self, role: str, block: Block, ctx: ControllerContext) -> None:
        value = self.settings["gain"] * float(block.values[-1]) + self.settings["offset"]
        if self._last is not None and abs(value - self._last) < self.settings["min_change"]:
            return
        self._last = ctx.set("output", self.settings["parameter"], value, sample_time=float(block.times[-1]))


class FollowTarget(Controller):
    """Turn an active mirror so that a tracked target stays in the camera's view (thesis §4.4).

    A plane mirror turned by θ turns the reflected line of sight by 2θ, so the mirror follows a
    target seen at direction θv from the mirror by θt = ``ratio`` · θv + offset (``ratio`` 0.5, the
    offset being half the camera's direction from the mirror), per axis. Each sample of the
    tracker's direction stream gives both axes; a sample flagged lost (``lost_column`` > 0) or
    holding NaN sends nothing, so the mirror stays where the target was last seen. Angles in rad.
    """

    name = "follow_target"
    version = "1.0.0"
    description = "active mirror follows a direction tracker: mirror angle = ratio * target direction + offset"
    parameters = ParameterSet(
        Parameter("ratio", float, 0.5, bounds=(-10.0, 10.0), help="mirror angle per target angle (0.5: theta_t = theta_v / 2)"),
        Parameter("h_offset", float, 0.0, unit="rad", help="horizontal mirror angle for a target straight ahead"),
        Parameter("v_offset", float, 0.0, unit="rad", help="vertical mirror angle for a target straight ahead"),
        Parameter("h_column", int, 0, bounds=(0, None), help="column of the horizontal target angle in the input"),
        Parameter("v_column", int, 1, bounds=(0, None), help="column of the vertical target angle in the input"),
        Parameter("lost_column", int, 3, bounds=(-1, None),
                  help="column flagging a lost target (non-zero: send nothing); -1: the tracker has none"),
        Parameter("min_change", float, 0.0, unit="rad", bounds=(0.0, None),
                  help="smallest change of a mirror angle worth a command"),
    )
    inputs = {"direction": "a direction tracker's stream: one row per sample with the target's angles, rad"}
    commands = {"mirror": ("h_angle", "v_angle")}
    latest_only = True

    def setup(self, ctx: ControllerContext) -> None:
        self._last: dict[str, float] = {}

    def on_block(self, role: str, block: Block, ctx: ControllerContext) -> None:
        row = block.values[-1].ravel()
        s = self.settings
        if s["lost_column"] >= 0 and row[s["lost_column"]] != 0:
            return
        t = float(block.times[-1])
        mirror = ctx.instrument("mirror").parameters
        for name, column, offset in (("h_angle", s["h_column"], s["h_offset"]), ("v_angle", s["v_column"], s["v_offset"])):
            angle = s["ratio"] * float(row[column]) + offset
            if angle != angle or abs(angle - self._last.get(name, float("inf"))) < s["min_change"]:
                continue  # NaN: no direction in this sample
            lo, hi = mirror[name].bounds or (None, None)  # beyond its travel the mirror waits at the limit
            angle = min(max(angle, -math.inf if lo is None else lo), math.inf if hi is None else hi)
            self._last[name] = ctx.set("mirror", name, angle, sample_time=t)


CONTROLLERS = [Follow, FollowTarget]
