"""Framework adapters: the ``retarget`` algorithm (and the helpers its recipe step :mod:`.steps` and
:mod:`.cli` share).

=============  =====================================  =========================================
name           inputs                                 outputs
=============  =====================================  =========================================
``retarget``   joints (T, n + 1, 3) mm                q (T, dof) rad, f (T,) mm², joints
               (algorithm, ``Session.run``)           (T, N + 1, 3) mm, residuals (T, P) mm,
                                                      iterations, restarted, pairs
``retarget``   a BVH / C3D / TRC / TSV file or a      group ``/retarget/<name>``: the input
               session marker set (recipe step,        joints and time, and the filter's
               streamed through the filter)            outputs per frame
=============  =====================================  =========================================
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext

from .approximate import approximate, input_chain
from .chain import Chain
from .errors import SourceError
from .sources import Motion, read_bvh_chain, read_marker_chain, session_marker_chain
from .stream import Compute, FilterStats, MemorySink, RetargetFilter, Sink, poses

if TYPE_CHECKING:
    pass

__all__ = ["Retarget", "chain_from", "read_motion", "stream_motion", "CHAIN_PARAMETERS"]

CHAIN_PARAMETERS = (
    Parameter("lengths", float, unit="mm", shape=(None,),
              help="output link lengths, comma-separated, e.g. '295.9, 229.5'"),
    Parameter("axes", str, help="output joint axes, one string per joint, comma-separated, e.g. 'zyx,y'"),
    Parameter("method", str, "lm", choices=("lm", "paper"),
              help="lm: warm-started Levenberg-Marquardt with multistart fallback; paper: per-joint Newton sweeps"),
    Parameter("sweeps", int, 3, bounds=(0, None), help="paper: Newton sweeps per frame (0: until converged)"),
    Parameter("max_iter", int, 20, bounds=(1, None), help="lm: iterations per frame"),
    Parameter("distance", str, "segment", choices=("segment", "line"), help="distance of a joint to an input arm"),
)


def chain_from(params: Mapping[str, Any]) -> Chain:
    """The output :class:`Chain` of the validated ``lengths`` (mm) and ``axes`` parameters (base on the input root).

    Examples
    --------
    >>> chain_from({"lengths": (300.0, 250.0), "axes": "zyx, y"}).dof
    4
    """
    return Chain(list(params["lengths"]), [a.strip() for a in str(params["axes"]).split(",") if a.strip()])


def read_motion(path: Path, joints: list[str], scale: float = 1.0, skip: int = 0, dataset: str = "") -> Motion:
    """A chain's joint positions from a BVH file, a marker file or a session (``dataset`` under /markers)."""
    suffix = path.suffix.lower()
    if suffix == ".bvh":
        return read_bvh_chain(path, joints, scale, skip)
    if suffix in (".h5", ".hdf5"):
        if not dataset:
            raise SourceError(f"{path} is a session: name its marker set (dataset) under /markers")
        m = session_marker_chain(path, dataset, joints)
    else:
        m = read_marker_chain(path, joints)
    if scale != 1.0 or skip:
        m = Motion(m.joints[skip:] * scale, m.time[skip:], m.rate, m.names, m.source)
    return m


def stream_motion(motion: Motion, chain: Chain, params: Mapping[str, Any], sinks: list[Sink],
                  realtime: bool = False, rate: float = 0.0) -> tuple[FilterStats, MemorySink]:
    """Stream a recording through the filter at ``rate`` Hz (default: the recording's); returns the
    counters and a memory sink holding every published frame. In real time the multistart runs in
    a worker process and is adopted when ready; otherwise on the frame that needs it."""
    memory = MemorySink()
    compute = Compute(chain, input_chain(motion.joints).lengths, params["method"], sweeps=params["sweeps"] or 3,
                      max_iter=params["max_iter"], distance=params["distance"], fallback_delay=None if realtime else 0)
    stats = RetargetFilter(compute, rate or motion.rate, [memory, *sinks]).run(poses(motion.joints, motion.time),
                                                                               realtime)
    return stats, memory


class Retarget(Algorithm):
    """Approximate an input chain by an output chain in every frame (spec retargeting.md)."""

    name = "retarget"
    version = "0.1.0"
    description = "chain shape approximation: n-DOF input joints -> m-DOF output chain angles (Toguro & Hashimoto)"
    parameters = ParameterSet(*CHAIN_PARAMETERS)
    inputs = (Port("joints", "(T, n + 1, 3) input joint positions, root to tip; NaN where missing", "mm"),)
    outputs = (Port("q", "(T, dof) output joint angles, unwrapped", "rad"),
               Port("f", "(T,) evaluation function", "mm²"),
               Port("joints", "(T, N + 1, 3) output joint positions", "mm"),
               Port("residuals", "(T, P) distance of each paired output joint to its input arm", "mm"),
               Port("iterations", "(T,) LM iterations or Newton sweeps per frame"),
               Port("restarted", "(T,) the multistart ran"),
               Port("pairs", "(P, 2) output joint, input arm"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        context.progress(0, 1, "retargeting")
        res = approximate(np.asarray(inputs["joints"], float), chain_from(params), params["method"],
                          sweeps=params["sweeps"] or None, max_iter=params["max_iter"], distance=params["distance"],
                          progress=lambda done, total: context.progress(done, total, "retargeting"))
        context.progress(1, 1, "done")
        return {"q": res.q, "f": res.f, "joints": res.joints, "residuals": res.residuals,
                "iterations": res.iterations, "restarted": res.restarted, "pairs": res.pairs}
