"""The ``retarget`` recipe step: a motion file or session marker set streamed through the filter into
``/retarget/<name>``."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import Parameter, ParameterSet, Problem, Step, identifier_problem

from .algorithms import CHAIN_PARAMETERS, chain_from, read_motion, stream_motion
from .errors import ChainDefinitionError
from .stream import CSVSink, Sink

if TYPE_CHECKING:
    from mirrorlab.core import Registry, Session


class RetargetStep(Step):
    """Recipe step ``retarget``: stream a recorded chain through the filter into ``/retarget/<name>``.

    .. code-block:: toml

        [[steps]]
        action = "retarget"
        file = "../../shared/data/bvh/01_01.bvh"   # relative to the recipe; .bvh, .c3d, .trc, .tsv, .h5
        joints = "RightArm,RightForeArm,RightHand,RFingers"
        scale = 56.444                             # mm per file unit
        skip = 1                                   # drop leading frames (CMU T-pose)
        lengths = "295.9,229.5"
        axes = "zyx,y"
    """

    name = "retarget"
    version = "0.1.0"
    description = "stream a BVH / marker-file / session chain through the retargeting filter into the session"
    parameters = ParameterSet(
        Parameter("file", Path, help="motion file (.bvh, .c3d, .trc, .tsv) or session (.h5)"),
        Parameter("joints", str, help="input joints root to tip, comma-separated (markers: 'A+B' = midpoint)"),
        Parameter("dataset", str, "", help="marker set under /markers when file is a session"),
        Parameter("scale", float, 1.0, bounds=(0.0, None), help="mm per file length unit (CMU BVH: 56.444)"),
        Parameter("skip", int, 0, bounds=(0, None), help="leading frames to drop"),
        Parameter("name", str, "", help="group under /retarget (default: the file's stem)"),
        Parameter("csv", str, "", output="file", help="also write the frames to this CSV file"),
        *CHAIN_PARAMETERS,
    )

    @classmethod
    def check(cls, values: Mapping[str, Any], where: str, file: str | None, registry: Registry) -> list[Problem]:
        problems = []
        if values["name"] and (reason := identifier_problem(values["name"])):  # it names /retarget/<name>
            problems.append(Problem(f"{where}.name", reason, file))
        if not values["file"].is_file():
            problems.append(Problem(f"{where}.file", f"no such motion file {str(values['file'])!r}", file))
        try:
            chain_from(values)
        except ChainDefinitionError as exc:
            problems.append(Problem(f"{where}.lengths", str(exc), file))
        return problems

    def execute(self, session: Session, values: Mapping[str, Any]) -> None:
        motion = read_motion(Path(values["file"]), [j.strip() for j in values["joints"].split(",")], values["scale"],
                             values["skip"], values["dataset"])
        chain = chain_from(values)
        sinks: list[Sink] = [CSVSink(values["csv"], chain.dof)] if values["csv"] else []
        stats, memory = stream_motion(motion, chain, values, sinks)
        name = values["name"] or Path(values["file"]).stem
        out = memory.arrays()
        s = stats.summary()
        summary = (f"{motion.source}: {s['published']} frames, mean f {float(np.nanmean(out['f'])):.4g} mm², "
                   f"compute {s['latency_mean_ms']:.2f} ms mean, {s['missed_deadlines']} missed deadlines "
                   f"at {motion.rate:g} Hz")
        # the description is what `session info` and the summary of `mirrorlab run` show of the group
        session.write_group(f"retarget/{name}", {"input_joints": motion.joints, "input_time": motion.time, **out},
                            {"source": motion.source, "joints": ",".join(motion.names), "lengths": values["lengths"],
                             "axes": values["axes"], "method": values["method"], "rate_hz": motion.rate,
                             "units": "joints mm, q rad, f mm2, residuals mm, time s", "description": summary, **s})
        session.events.emit("info", "retarget", "retargeted", summary)
