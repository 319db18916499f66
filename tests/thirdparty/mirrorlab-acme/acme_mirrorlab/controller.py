"""The controller: an over-temperature alarm computed live from the thermometer's stream."""

from __future__ import annotations

from typing import Any

import numpy as np
from mirrorlab.core import Block, Controller, ControllerContext, Parameter, ParameterSet, StreamSpec


class AcmeAlarm(Controller):
    name = "acme_alarm"
    version = "0.3.0"
    description = "over-temperature alarm with hysteresis: 1 above `high`, 0 again below `low`"
    parameters = ParameterSet(
        Parameter("high", float, 293.2, unit="K", help="raise the alarm above this temperature"),
        Parameter("low", float, 293.18, unit="K", help="clear the alarm below this temperature"),
    )
    inputs = {"temperature": "a temperature stream, K"}

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.on = False

    def streams(self) -> list[StreamSpec]:
        return [StreamSpec("alarm", "u1", (), "", None, "1 while over temperature")]

    def on_block(self, role: str, block: Block, ctx: ControllerContext) -> None:
        flags = np.empty(len(block.times), np.uint8)
        for i, kelvin in enumerate(block.values):
            self.on = bool(kelvin > self.settings["high"] or (self.on and kelvin >= self.settings["low"]))
            flags[i] = self.on
        ctx.emit("alarm", block.times, flags)
