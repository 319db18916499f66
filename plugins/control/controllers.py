"""The built-in controllers (adapters of :class:`mirrorlab.core.controllers.Controller`)."""

from __future__ import annotations

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


CONTROLLERS = [Follow]
