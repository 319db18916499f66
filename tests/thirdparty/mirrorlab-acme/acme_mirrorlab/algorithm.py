"""An algorithm: the linear drift rate of a stream (least squares), in value units per second."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import Algorithm, AlgorithmError, Parameter, ParameterSet, Port, RunContext


class DriftRate(Algorithm):
    name = "acme_drift_rate"
    version = "0.3.0"
    description = "least-squares linear drift of a scalar stream"
    parameters = ParameterSet(
        Parameter("skip", float, 0.0, unit="s", bounds=(0.0, None), help="ignore the first seconds"),
    )
    inputs = (Port("time", "(n,) sample times", "s"), Port("values", "(n,) samples"))
    outputs = (Port("rate", "() drift per second", "{values}/s"), Port("offset", "() value at t = 0", "{values}"),
               Port("residual_rms", "() fit RMS", "{values}"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        t, v = np.asarray(inputs["time"], float), np.asarray(inputs["values"], float)
        keep = t >= t[0] + params["skip"] if len(t) else np.zeros(0, bool)
        if keep.sum() < 2:
            raise AlgorithmError(f"need at least 2 samples after skip={params['skip']} s, got {int(keep.sum())}; "
                                 "record longer or lower skip")
        context.progress(0, 1, "fitting")
        coef, *_ = np.linalg.lstsq(np.column_stack([t[keep], np.ones(keep.sum())]), v[keep], rcond=None)
        residual = v[keep] - (coef[0] * t[keep] + coef[1])
        context.progress(1, 1, "done")
        return {"rate": coef[0], "offset": coef[1], "residual_rms": float(np.sqrt(np.mean(residual ** 2)))}
