"""Algorithm plugin: real/mirror pairing frame by frame, with continuity from the previous frame."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext

from .errors import InvalidPairingInput
from .pair import pair_mirror


class PairMirror(Algorithm):
    """For each real marker and mirror: the index and position of its mirror image, or −1 / NaN."""

    name = "pair_mirror"
    version = "0.1.0"
    description = "pair markers with their mirror images through the mirror epipole (ambiguity reported)"
    parameters = ParameterSet(
        Parameter("tol", float, 2.0, bounds=(0.0, None), help="largest epipolar distance of a pair, px"),
        Parameter("margin", float, 0.0, bounds=(0.0, None),
                  help="alternatives within this cost make a pair ambiguous, px (0: tol)"),
        Parameter("continuity", bool, True, help="prefer pairs continuing the previous frame's pairs"),
        Parameter("motion_gate", float, 20.0, bounds=(0.0, None), help="largest image motion per frame, px"),
    )
    inputs = (Port("real", "(F, N, 2) direct marker images, NaN-padded (undistorted)", "px"),
              Port("virtual", "(F, M, 2) mirror-image detections, NaN-padded (undistorted)", "px"),
              Port("epipoles", "(E, 3) homogeneous mirror epipoles (mirror_epipole), or (E, 2)", "px"),
              Port("virtual_mirror", "(F, M) mirror of each virtual detection, -1 unknown", optional=True))
    outputs = (Port("virtual_index", "(F, N, E) index of the mirror image per mirror, -1 none"),
               Port("virtual_xy", "(F, N, E, 2) position of the mirror image, NaN none", "px"),
               Port("cost", "(F, N, E) epipolar distance of the pair, NaN none", "px"),
               Port("ambiguous", "(F, N, E) the pairing was ambiguous (and left undecided)"),
               Port("n_ambiguous", "(F,) ambiguous pairs per frame"))
    frame_inputs = ("real", "virtual", "virtual_mirror")

    @classmethod
    def frame_wise(cls, params: Mapping[str, Any]) -> tuple[str, ...]:
        """Frames pair on their own only without continuity (which looks at the previous frame)."""
        return () if params["continuity"] else cls.frame_inputs

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        real, virt = np.asarray(inputs["real"], float), np.asarray(inputs["virtual"], float)
        if real.ndim == 2:
            real, virt = real[None], virt[None]
        if real.ndim != 3 or virt.ndim != 3 or real.shape[2] != 2 or virt.shape[2] != 2 or len(real) != len(virt):
            raise InvalidPairingInput(f"real and virtual must be (F, N, 2) and (F, M, 2) with the same F, got "
                                      f"{real.shape} and {virt.shape}")
        epi = np.asarray(inputs["epipoles"], float)
        n_mirrors = 1 if epi.ndim == 1 else epi.shape[0]
        vm_all = inputs.get("virtual_mirror")
        n_frames, n = real.shape[:2]
        index = np.full((n_frames, n, n_mirrors), -1, np.int64)
        vxy = np.full((n_frames, n, n_mirrors, 2), np.nan)
        cost = np.full((n_frames, n, n_mirrors), np.nan)
        amb = np.zeros((n_frames, n, n_mirrors), bool)
        previous = None
        for f in range(n_frames):
            ri = np.flatnonzero(np.all(np.isfinite(real[f]), axis=1))
            vi = np.flatnonzero(np.all(np.isfinite(virt[f]), axis=1))
            vm = None if vm_all is None else np.asarray(vm_all)[f, vi]
            try:
                res = pair_mirror(real[f, ri], virt[f, vi], epi, tol=params["tol"], virtual_mirror=vm,
                                  previous=previous if params["continuity"] else None,
                                  motion_gate=params["motion_gate"], margin=params["margin"] or None)
            except InvalidPairingInput as exc:
                raise InvalidPairingInput(f"frame {f}: {exc}") from None
            r, v, k = res.pairs.T
            index[f, ri[r], k] = vi[v]
            vxy[f, ri[r], k] = virt[f, vi[v]]
            cost[f, ri[r], k] = res.cost
            for a in res.ambiguous:
                amb[f, ri[a.real], a.mirror] = True
            previous = (real[f, ri[r]], virt[f, vi[v]], k)
            if f % 256 == 0:
                context.progress(f, n_frames, "pairing")
        context.progress(n_frames, n_frames, "pairing")
        return {"virtual_index": index, "virtual_xy": vxy, "cost": cost, "ambiguous": amb,
                "n_ambiguous": amb.sum(axis=(1, 2))}


ALGORITHMS = [PairMirror]
