"""Algorithm plugin: frame-to-frame tracking of NaN-padded detections."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext

from .errors import InvalidDetections
from .track import track


class Track(Algorithm):
    """Tracks (frames, tracks, 2) with NaN gaps from per-frame detections (frames, K_max, 2)."""

    name = "track"
    version = "0.1.0"
    description = "marker tracks: constant-velocity prediction + optimal assignment, or the thesis's nearest neighbour"
    parameters = ParameterSet(
        Parameter("method", str, "predictive", choices=("predictive", "nearest"),
                  help="predictive: constant velocity + Hungarian assignment; nearest: thesis rule"),
        Parameter("gate", float, 20.0, bounds=(0.0, None), help="largest distance to the prediction, px"),
        Parameter("initial_gate", float, 0.0, bounds=(0.0, None),
                  help="gate of tracks with one detection, px (0: twice the gate)"),
        Parameter("max_gap", int, 5, bounds=(0, None), help="frames a track may be missing and keep its id"),
        Parameter("min_length", int, 1, bounds=(1, None), help="drop tracks with fewer detections"),
    )
    inputs = (Port("detections", "(F, K_max, 2) detections, NaN-padded", "px"),
              Port("counts", "(F,) valid rows per frame (rows beyond are ignored)", optional=True))
    outputs = (Port("xy", "(F, T, 2) tracks, NaN where missing", "px"),
               Port("index", "(F, T) detection index per frame, -1 where missing"),
               Port("present", "(T,) fraction of frames present between first and last"),
               Port("residual", "(T,) mean distance to the prediction", "px"),
               Port("first", "(T,) first frame"), Port("last", "(T,) last frame"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        det = np.asarray(inputs["detections"], float)
        if det.ndim != 3 or det.shape[2] != 2:
            raise InvalidDetections(f"detections must have shape (F, K_max, 2) px, got {det.shape}; "
                                    "use the xy output of detect_markers")
        if "counts" in inputs:
            counts = np.asarray(inputs["counts"]).reshape(-1)
            if counts.shape != (det.shape[0],):
                raise InvalidDetections(f"counts must have shape ({det.shape[0]},), got {counts.shape}")
            det = det.copy()
            det[np.arange(det.shape[1])[None, :] >= counts[:, None]] = np.nan
        out = track(det, params["method"], gate=params["gate"], initial_gate=params["initial_gate"] or None,
                    max_gap=params["max_gap"], min_length=params["min_length"],
                    progress=lambda done, total: context.progress(done, total, "tracking"))
        return {"xy": out.xy, "index": out.index, "present": out.present, "residual": out.residual,
                "first": out.first, "last": out.last}


ALGORITHMS = [Track]
