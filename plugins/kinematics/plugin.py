"""Algorithm plugins that adapt the kinematics functions to sessions, recipes and the CLI."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext

from .derivatives import derivatives


class Derivatives(Algorithm):
    """Smoothed positions, velocities and accelerations of any sampled signal (time on axis 0)."""

    name = "derivatives"
    version = "0.1.0"
    description = "smoothed values, velocity and acceleration (thesis spline, smoothing spline, Butterworth)"
    parameters = ParameterSet(
        Parameter("method", str, "smoothing_spline", choices=("smoothing_spline", "thesis_spline", "butterworth"),
                  help="differentiation method"),
        Parameter("cutoff", float, 6.0, unit="Hz", bounds=(0.01, None), help="Butterworth cut-off frequency"),
        Parameter("order", int, 2, bounds=(1, 8), help="Butterworth order (zero-phase, so doubled)"),
        Parameter("max_gap", int, 0, bounds=(0, None), help="bridge NaN gaps up to this many samples (0: never)"),
    )
    inputs = (Port("time", "(T,) sample times", "s"), Port("values", "(T, ...) samples, NaN where missing"))
    outputs = (Port("smoothed", "(T, ...) smoothed values"), Port("velocity", "(T, ...) first derivative, unit/s"),
               Port("acceleration", "(T, ...) second derivative, unit/s²"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        extra: dict[str, Any] = {"max_gap": params["max_gap"]} if params["max_gap"] else {}
        if params["method"] == "butterworth":
            extra.update(cutoff=params["cutoff"], order=params["order"])
        context.progress(0, 1, params["method"])
        smoothed, velocity, acceleration = derivatives(inputs["time"], np.asarray(inputs["values"], float),
                                                       params["method"], **extra)
        context.progress(1, 1, "done")
        return {"smoothed": smoothed, "velocity": velocity, "acceleration": acceleration}
