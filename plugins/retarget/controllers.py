"""The ``retarget`` controller: the streaming filter (spec §7) as a runtime controller.

The session's router is the input module (every input sample, in order), :class:`~.stream.Compute`
the compute module and the controller's streams (optionally set-points to instruments) the output
module. Input: a live joint-position stream (a motion-capture skeleton: one (n + 1, 3) sample per
frame, mm), or the joint angles of a virtual input chain (``input_lengths`` and ``input_axes``:
one (dof_in,) sample, rad). Output streams, each stamped with its input sample's time: ``q``
(dof,) rad, ``f`` mm², ``joints`` (N + 1, 3) mm, ``compute_latency`` s (output time minus input
sample time) and ``missed`` (missed deadlines so far).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import (
    Block,
    Controller,
    ControllerContext,
    Parameter,
    ParameterSet,
    Problem,
    StreamSpec,
    ValidationError,
)

from .algorithms import CHAIN_PARAMETERS, chain_from
from .chain import Chain
from .errors import ChainDefinitionError
from .stream import Compute

__all__ = ["RetargetController"]


def _ints(text: str) -> tuple[int, ...]:
    return tuple(int(k) for k in text.replace(" ", "").split(",") if k)


class RetargetController(Controller):
    """Retarget a live input chain onto an output chain, sample by sample (spec §7).

    Every input sample is computed once, in order (``latest_only = False``): with
    ``multistart = "frame"`` the output is :func:`~.approximate.approximate` of the same input
    frames (strictly sequential, to round-off). ``multistart = "worker"`` runs the multistart in a
    niced worker process and adopts its result on a later frame (real time; see
    ``docs/retarget.md``). A deadline is missed when an output leaves later than one period after
    its input sample (period ``1 / rate``; ``rate = 0``: the input's own spacing, the time since
    the previous sample). ``actuate = "0,3"`` also sends q0 and q3, wrapped to (−π, π], as the
    live parameter ``parameter`` of the instruments bound to roles ``q0`` and ``q3``.

    Units: mm, rad, s; f in mm².
    """

    name = "retarget"
    version = "0.1.0"
    description = "stream a live chain (joint positions or virtual-chain angles) through the retargeting filter"
    parameters = ParameterSet(
        *CHAIN_PARAMETERS,
        Parameter("input_lengths", float, (), unit="mm", shape=(None,),
                  help="virtual input chain: its link lengths (the input stream then holds its joint angles, rad); "
                       "empty: the input stream holds joint positions, mm"),
        Parameter("input_axes", str, "", help="virtual input chain: its joint axes, comma-separated, e.g. 'z,z,z,z'"),
        Parameter("arm_lengths", float, (), unit="mm", shape=(None,),
                  help="input arm lengths for the correspondence (spec §3); empty: those of the first complete pose"),
        Parameter("rate", float, 0.0, unit="Hz", bounds=(0.0, None),
                  help="deadline = one period of this rate; 0: the input's own sample spacing"),
        Parameter("multistart", str, "frame", choices=("frame", "worker"),
                  help="frame: on the frame that needs it (deterministic, the batch result); "
                       "worker: in a niced worker process, adopted when ready (real time)"),
        Parameter("actuate", str, "", help="output angles to command, comma-separated indices, e.g. '3' "
                                           "(instrument roles q3...)"),
        Parameter("parameter", str, "target", help="the live parameter of each actuated instrument"),
        Parameter("wait", bool, True,
                  help="true: each set-point is acknowledged before the next frame is computed (every frame "
                       "reaches the actuators); false: set-points leave from a sender thread, a newer one "
                       "replacing one not yet sent (real time: the filter never waits for an actuator)"),
    )
    inputs = {"input": "joint positions (n + 1, 3) mm per sample, or the virtual input chain's joint angles, rad"}
    latest_only = False

    def __init__(self, label: str, settings: Mapping[str, Any] | None = None) -> None:
        super().__init__(label, settings)
        where = f"controllers.{label}.settings"
        s = self.settings
        problems = []
        try:
            self.chain = chain_from(s)
        except ChainDefinitionError as exc:
            problems.append(Problem(f"{where}.lengths", str(exc)))
        self.input_chain: Chain | None = None
        if s["input_lengths"] or s["input_axes"]:
            try:
                self.input_chain = Chain(list(s["input_lengths"]), [a.strip() for a in s["input_axes"].split(",")])
            except ChainDefinitionError as exc:
                problems.append(Problem(f"{where}.input_axes", str(exc)))
        try:
            self.actuated = _ints(s["actuate"])
        except ValueError:
            self.actuated = ()
            problems.append(Problem(f"{where}.actuate", f"{s['actuate']!r} is not a list of angle indices like '0,3'"))
        if not problems and any(not 0 <= k < self.chain.dof for k in self.actuated):
            problems.append(Problem(f"{where}.actuate", f"indices must lie in 0..{self.chain.dof - 1} "
                                                        f"(the output chain has {self.chain.dof} angles)"))
        if problems:
            raise ValidationError(problems)

    def commanded(self) -> Mapping[str, tuple[str, ...]]:
        return {f"q{k}": (self.settings["parameter"],) for k in self.actuated}

    def streams(self) -> list[StreamSpec]:
        rate = self.settings["rate"] or None
        return [StreamSpec("q", "f8", (self.chain.dof,), "rad", rate, "output joint angles, unwrapped"),
                StreamSpec("f", "f8", (), "mm²", rate, "evaluation function at q"),
                StreamSpec("joints", "f8", (self.chain.n_links + 1, 3), "mm", rate, "output joint positions"),
                StreamSpec("compute_latency", "f8", (), "s", rate, "output time minus input sample time"),
                StreamSpec("missed", "i8", (), "", rate, "deadlines missed so far")]

    # -- the loop --------------------------------------------------------------------------------
    def setup(self, ctx: ControllerContext) -> None:
        self.compute: Compute | None = None
        self.missed = 0
        self.outputs = 0
        self._latencies: list[float] = []
        self._previous: float | None = None
        if self.settings["arm_lengths"] or self.input_chain is not None:   # known: start a worker before the clock
            self.compute = self._open(None)

    def _pose(self, values: np.ndarray) -> np.ndarray:
        """Input joint positions (n + 1, 3) mm of one sample."""
        if self.input_chain is not None:
            return self.input_chain.forward(np.asarray(values, float).reshape(1, -1))[0]
        return np.asarray(values, float).reshape(-1, 3)

    def _open(self, X: np.ndarray | None) -> Compute:
        """The compute module, its correspondence from ``arm_lengths``, the virtual chain or the pose ``X``."""
        if self.settings["arm_lengths"]:
            lengths = np.asarray(self.settings["arm_lengths"])
        elif self.input_chain is not None:
            lengths = self.input_chain.lengths
        else:
            assert X is not None
            lengths = np.linalg.norm(np.diff(X, axis=0), axis=1)
        s = self.settings
        compute = Compute(self.chain, lengths, s["method"], sweeps=s["sweeps"] or 3, max_iter=s["max_iter"],
                          distance=s["distance"], fallback_delay=0 if s["multistart"] == "frame" else None)
        compute.open()
        return compute

    def on_block(self, role: str, block: Block, ctx: ControllerContext) -> None:
        try:
            for t, values in zip(block.times.tolist(), block.values):
                self._sample(float(t), self._pose(values), ctx)
        except BaseException:
            self._close()
            raise

    def _sample(self, t: float, X: np.ndarray, ctx: ControllerContext) -> None:
        if self.compute is None:
            if not np.isfinite(X).all():
                return                                  # no output before the first complete pose
            self.compute = self._open(X)
        q, f, *_ = self.compute(X)
        now = ctx.now()
        latency = now - t
        rate = self.settings["rate"]
        period = 1.0 / rate if rate else (t - self._previous if self._previous is not None else math.inf)
        self._previous = t
        self.missed += latency > period
        self.outputs += 1
        self._latencies.append(latency)
        joints = self.chain.forward(q[None])[0] if np.isfinite(q).all() else np.full((self.chain.n_links + 1, 3), np.nan)
        ctx.emit("q", [t], q[None])
        ctx.emit("f", [t], [f])
        ctx.emit("joints", [t], joints[None] + (X[0] if self.chain.base is None else 0.0))
        ctx.emit("compute_latency", [t], [latency])
        ctx.emit("missed", [t], [self.missed])
        if np.isfinite(q).all():
            command = ctx.set if self.settings["wait"] else ctx.send
            for k in self.actuated:
                command(f"q{k}", self.settings["parameter"], math.remainder(float(q[k]), 2 * math.pi), sample_time=t)

    def _close(self) -> None:
        if getattr(self, "compute", None) is not None:
            self.compute.close()
            self.compute = None

    def teardown(self, ctx: ControllerContext) -> None:
        self._close()
