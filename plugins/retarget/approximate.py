"""Frame-by-frame shape approximation of an input chain by an output chain (spec §3–§6, §8).

:func:`approximate` is the batch entry point; :class:`Tracker` is the per-frame step it shares
with the streaming filter (:mod:`.stream`): solve from the previous frame's angles (``lm``: one
warm-started Levenberg–Marquardt solve; ``paper``: K per-joint Newton sweeps), fall back to a
multistart when f jumps by more than a factor, and unwrap the angles so that they never jump by
2π. Units: mm, rad, f in mm².
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .chain import Tree, as_base
from .correspondence import correspondence_pairs, serial_parents
from .errors import InputChainError, RetargetError, TopologyError
from .objective import Arms, Objective
from .solvers import Solution, levenberg_marquardt, multistart, paper_sweeps, start_points

__all__ = ["approximate", "Approximation", "Tracker", "InputChain", "input_chain", "METHODS", "unwrap_to"]

FloatArray = NDArray[np.float64]
METHODS = ("lm", "paper")


# ------------------------------------------------------------------------------------------------
# input chain validation (spec §8)
# ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class InputChain:
    """Validated input: positions (T, n_nodes, 3) mm, node parents, median arm lengths and drift.

    ``valid[t]`` is False for frames with a missing (NaN) joint or a zero-length arm.
    ``deviation[t, a]`` is ``|length / median − 1|`` of arm ``a`` in frame ``t`` (NaN if invalid).
    """

    joints: FloatArray
    parents: NDArray[np.int64]
    lengths: FloatArray
    deviation: FloatArray
    valid: NDArray[np.bool_]


def input_chain(input_joints: ArrayLike, input_parents: ArrayLike | None = None, drift_tol: float = 0.05) -> InputChain:
    """Validate input joint positions and fix each arm's length to its median (spec §8).

    Parameters
    ----------
    input_joints : array_like (T, n_nodes, 3) or (T, n_nodes, 2)
        Joint positions in mm, NaN where missing; 2-D input is placed in the plane z = 0.
    input_parents : array_like (n_nodes,), optional
        Node parents for a branched input; default serial.
    drift_tol : float
        Warn (:class:`~.errors.LengthDriftWarning`) when an arm deviates from its median length
        by more than this fraction in some frame.

    Raises
    ------
    InputChainError
        Wrong shape, no frame with every joint present, or an arm of zero median length.
    TopologyError
        Invalid ``input_parents``.

    Examples
    --------
    >>> ic = input_chain([[[0, 0, 0], [1, 0, 0], [1, 2, 0]]])
    >>> ic.lengths.tolist(), ic.valid.tolist()
    ([1.0, 2.0], [True])
    """
    from .errors import LengthDriftWarning

    X = np.asarray(input_joints, float)
    if X.ndim != 3 or X.shape[-1] not in (2, 3) or X.shape[1] < 2 or X.shape[0] < 1:
        raise InputChainError(f"input joints must have shape (frames, joints >= 2, 3) mm (or 2 coordinates), "
                              f"got {X.shape}")
    if X.shape[-1] == 2:
        X = np.concatenate([X, np.zeros(X.shape[:2] + (1,))], axis=-1)
    n = X.shape[1]
    par = serial_parents(n) if input_parents is None else np.asarray(input_parents, np.int64).reshape(-1)
    if par.size != n or par[0] != -1 or np.any(par[1:] < 0) or np.any(par[1:] >= np.arange(1, n)):
        raise TopologyError(f"input_parents {par.tolist()} must give -1 for node 0 and an earlier node for each "
                            f"of the other {n - 1} nodes")
    seg = np.linalg.norm(X[:, 1:] - X[:, par[1:]], axis=-1)               # (T, n - 1)
    present = np.isfinite(X).all(axis=(1, 2))
    if not present.any():
        raise InputChainError(f"no frame of the {X.shape[0]} has all {n} input joints present; "
                              "fill the gaps or choose joints that are tracked")
    lengths = np.median(seg[present], axis=0)
    if np.any(lengths <= 0):
        a = int(np.flatnonzero(lengths <= 0)[0])
        raise InputChainError(f"input arm {a} (joint {par[a + 1]} to joint {a + 1}) has zero median length; "
                              "two input joints coincide - check the joint (marker) selection")
    valid = present & np.all(seg > 1e-9 * lengths, axis=1)
    deviation = np.where(valid[:, None], np.abs(seg / lengths - 1.0), np.nan)
    if valid.any() and np.nanmax(deviation) > drift_tol:
        worst = np.nanmax(deviation, axis=0)
        a = int(np.argmax(worst))
        frames = int(np.sum(deviation[:, a] > drift_tol))
        t = int(np.nanargmax(deviation[:, a]))
        warnings.warn(f"input arm {a} deviates from its median length {lengths[a]:.4g} mm by more than "
                      f"{100 * drift_tol:g} % in {frames} frames (worst {100 * worst[a]:.3g} % at frame {t}); "
                      "the correspondence uses the median lengths", LengthDriftWarning, stacklevel=3)
    if (~valid & present).any():
        t = int(np.flatnonzero(~valid & present)[0])
        warnings.warn(f"input frame {t}: an arm has zero length; the frame is skipped (NaN output)",
                      LengthDriftWarning, stacklevel=3)
    return InputChain(X, par, lengths, deviation, valid)


def unwrap_to(q: FloatArray, ref: FloatArray, chain: Tree) -> FloatArray:
    """Shift unlimited angles of q by multiples of 2π to lie within π of ``ref`` (rad)."""
    return np.where(chain.unlimited, q - 2 * np.pi * np.round((q - ref) / (2 * np.pi)), q)


# ------------------------------------------------------------------------------------------------
# one frame step, shared by the batch and the streaming filter
# ------------------------------------------------------------------------------------------------
class Tracker:
    """Per-frame solve with warm start, multistart fallback and unwrapping (spec §5–§6).

    Parameters
    ----------
    objective : Objective
    method : {"lm", "paper"}
    sweeps : int or None
        ``paper``: sweeps per frame (None: until converged).
    max_iter : int
        ``lm``: iterations per frame.
    use_multistart : bool
        Run the multistart on the first frame, after a gap, and when f jumps.
    n_starts : int
        Random starts of the multistart (fixed per tracker, so every frame sees the same ones).
    jump_factor, jump_abs : float
        The multistart runs when ``f > jump_factor · f_previous + jump_abs`` (mm²).
    seed : int
        Seed of the start points.
    """

    def __init__(self, objective: Objective, method: str = "lm", sweeps: int | None = None, max_iter: int = 20,
                 use_multistart: bool = True, n_starts: int = 8, jump_factor: float = 2.0,
                 jump_abs: float | None = None, seed: int = 0) -> None:
        if method not in METHODS:
            raise RetargetError(f"unknown method {method!r}; use one of {METHODS}")
        self.objective = objective
        self.method = method
        self.sweeps = sweeps
        self.max_iter = max_iter
        self.use_multistart = use_multistart
        self.starts = start_points(objective, n_starts, seed)
        self.jump_factor = jump_factor
        total = float(objective.output.lengths.sum())
        self.jump_abs = (1e-3 * total) ** 2 if jump_abs is None else float(jump_abs)

    def solve(self, q_prev: FloatArray, arms: Arms, R_b: FloatArray, p_b: FloatArray) -> Solution:
        """The warm-started solve of B rows from ``q_prev`` (B, dof) rad: one LM solve or K sweeps."""
        if self.method == "lm":
            return levenberg_marquardt(self.objective, q_prev, arms, R_b, p_b, max_iter=self.max_iter)
        return paper_sweeps(self.objective, q_prev, arms, R_b, p_b, sweeps=self.sweeps)

    def triggers(self, f: FloatArray, f_prev: FloatArray, has_prev: NDArray[np.bool_]) -> NDArray[np.bool_]:
        """Rows (B,) that need the multistart: no previous frame, or f (mm²) jumped (spec §6)."""
        if not self.use_multistart:
            return np.zeros(f.shape, bool)
        return ~has_prev | (f > self.jump_factor * f_prev + self.jump_abs)

    def fallback(self, arms: Arms, R_b: FloatArray, p_b: FloatArray, warm: FloatArray) -> Solution:
        """The multistart of B rows: the fixed starts and the warm solution ``warm`` (B, dof) rad."""
        return multistart(self.objective, self.starts, arms, R_b, p_b, extra=warm)

    def step(self, q_prev: FloatArray, f_prev: FloatArray, has_prev: NDArray[np.bool_], arms: Arms,
             R_b: FloatArray, p_b: FloatArray) -> tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.bool_],
                                                        FloatArray]:
        """Solve B rows of one step: angles (B, dof), f (B,), iterations (B,), restarted (B,), residuals (B, P, 3).

        ``q_prev`` is the warm start (the previous frame's angles, or the initial angles where
        ``has_prev`` is False); ``arms`` the input arms of the B rows (:meth:`.Objective.arms`). The
        multistart runs here, on the frame that needs it (synchronously).
        """
        sol = self.solve(q_prev, arms, R_b, p_b)
        q, f, iters, res = sol.q, sol.f, sol.iterations, sol.residuals
        restarted = self.triggers(f, f_prev, has_prev)
        rows = np.flatnonzero(restarted)
        if rows.size:
            ms = self.fallback(arms.take(rows), R_b[rows] if R_b.ndim == 3 else R_b, p_b[rows] if p_b.ndim == 2 else p_b,
                               q[rows])
            q[rows], f[rows], res[rows] = ms.q, ms.f, ms.residuals
            iters[rows] += ms.iterations
        ref = np.where(has_prev[:, None], q_prev, 0.0)
        return unwrap_to(q, ref, self.objective.output), f, iters, restarted, res


# ------------------------------------------------------------------------------------------------
# batch
# ------------------------------------------------------------------------------------------------
@dataclass
class Approximation:
    """Result of :func:`approximate`; arrays over T frames, NaN for skipped frames.

    Attributes
    ----------
    q : ndarray (T, dof)
        Output joint angles, rad, unwrapped (continuous across frames).
    f : ndarray (T,)
        Evaluation function at q, mm².
    joints : ndarray (T, N_out + 1, 3)
        Output joint positions, mm.
    residuals : ndarray (T, P)
        Distance of each paired output joint to its input arm, mm (P = N_out + 1 for chains).
    iterations : ndarray (T,)
        LM iterations or Newton sweeps spent on the frame (multistart included).
    restarted : ndarray (T,) of bool
        The multistart ran on this frame.
    flagged : ndarray (T,) of bool
        ``f`` exceeded ``flag_above``.
    pairs : ndarray (P, 2)
        (output joint, input arm) correspondence.
    input : InputChain
        The validated input (median arm lengths, length deviation per frame).
    method : str
    """

    q: FloatArray
    f: FloatArray
    joints: FloatArray
    residuals: FloatArray
    iterations: NDArray[np.int64]
    restarted: NDArray[np.bool_]
    flagged: NDArray[np.bool_]
    pairs: NDArray[np.int64]
    input: InputChain
    method: str

    def jumps(self, threshold: float = 0.5) -> NDArray[np.int64]:
        """Frames ``t`` whose angles differ from frame ``t − 1`` by more than ``threshold`` rad (any angle)."""
        d = np.abs(np.diff(self.q, axis=0)).max(axis=1)
        return np.flatnonzero(d > threshold) + 1


def _bases(chain: Tree, ic: InputChain, base: Any) -> tuple[FloatArray, FloatArray]:
    """Output base per frame: given, the chain's own, or (identity, input root) when neither is set."""
    T = ic.joints.shape[0]
    if base is not None:
        R, p = as_base(base)
    elif chain.base is not None:
        R, p = chain.base
    else:
        R, p = np.eye(3), ic.joints[:, 0]
    if R.ndim == 3 and R.shape[0] != T or p.ndim == 2 and p.shape[0] != T:
        raise InputChainError(f"a per-frame base must have {T} frames like the input; got R {R.shape}, p {p.shape}")
    return R, np.broadcast_to(p, (T, 3))


def _track(tracker: Tracker, X: FloatArray, valid: NDArray[np.bool_], R: FloatArray, p: FloatArray,
           schedule: NDArray[np.int64], q_init: FloatArray, f_init: FloatArray,
           has_init: NDArray[np.bool_], progress: Callable[[int, int], None] | None = None,
           ) -> tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.bool_]]:
    """Run rows of frames in lockstep; ``schedule`` (B, S) holds frame indices, -1 for padding.

    ``progress(s, S)`` is called before each lockstep ``s`` of ``S``.
    """
    B, S = schedule.shape
    m = q_init.shape[1]
    q_out = np.full((B, S, m), np.nan)
    f_out = np.full((B, S), np.nan)
    it_out = np.zeros((B, S), np.int64)
    rs_out = np.zeros((B, S), bool)
    q, f, has = q_init.copy(), f_init.copy(), has_init.copy()
    for s in range(S):
        if progress is not None:
            progress(s, S)
        frames = schedule[:, s]
        live = frames >= 0
        ok = live & valid[np.maximum(frames, 0)]
        has[live & ~ok] = False                      # a gap: restart after it
        rows = np.flatnonzero(ok)
        if rows.size == 0:
            continue
        fr = frames[rows]
        qs, fs, its, rss, _ = tracker.step(q[rows], f[rows], has[rows], tracker.objective.arms(X[fr]),
                                           R[fr] if R.ndim == 3 else R, p[fr])
        q[rows], f[rows], has[rows] = qs, fs, True
        q_out[rows, s], f_out[rows, s], it_out[rows, s], rs_out[rows, s] = qs, fs, its, rss
    return q_out, f_out, it_out, rs_out


def approximate(input_joints: ArrayLike, chain: Tree, method: str = "lm", *, input_parents: ArrayLike | None = None,
                leaf_map: Sequence[int] | None = None, distance: str = "segment", base: Any = None,
                q0: ArrayLike | None = None, sweeps: int | None = None, max_iter: int = 20,
                multistart: bool | None = None, n_starts: int = 8, jump_factor: float = 2.0,
                jump_abs: float | None = None, block: int = 32, drift_tol: float = 0.05,
                flag_above: float = np.inf, seed: int = 0,
                progress: Callable[[int, int], None] | None = None) -> Approximation:
    """Approximate the shape of an input chain by an output chain in every frame.

    Parameters
    ----------
    input_joints : array_like (T, n + 1, 3)
        Input joint positions in mm (NaN where missing; such frames give NaN output and the
        next valid frame restarts).
    chain : Chain or Tree
        Output chain; its base ``None`` puts the output base on the input's root joint in
        every frame with the identity rotation.
    method : {"lm", "paper"}
        ``lm``: simultaneous least squares (Levenberg–Marquardt, analytic Jacobian, spec §6);
        ``paper``: per-joint Newton sweeps (spec §5).
    input_parents : array_like, optional
        Node parents of a branched input (spec §10); ``leaf_map`` maps output leaves to input leaves.
    distance : {"segment", "line"}
        Distance of a joint to an input arm.
    base : optional
        Output base pose for all frames or per frame (R (T, 3, 3), p (T, 3)); overrides the chain's.
    q0 : array_like (dof,), optional
        Start angles of the first frame (default 0).
    sweeps : int or None
        ``paper``: sweeps per frame, None = until converged.
    max_iter : int
        ``lm``: iterations per frame.
    multistart : bool, optional
        Multistart fallback (default: on for ``lm``, off for ``paper``, which is the paper's scheme).
    n_starts, jump_factor, jump_abs, seed
        Multistart settings (see :class:`Tracker`).
    block : int
        ``lm`` with multistart: frames per block of the parallel batch (0: strictly sequential).
        Blocks start with a multistart 16 frames early; a block whose first frame does not agree
        (1e-6 rad) with its predecessor's continuation is re-solved sequentially, so the result is
        the sequential one.
    drift_tol : float
        Input arm length tolerance (fraction) for the drift warning.
    flag_above : float
        Flag frames with f above this (mm²).
    progress : callable, optional
        Called as ``progress(done, total)`` between steps of the frame loop; an exception it raises
        (a cancelled run) ends the approximation.

    Returns
    -------
    Approximation

    Examples
    --------
    The spec's fixture T1 (4 → 2 DOF):

    >>> from mirrorlab.plugins.retarget import Chain
    >>> X = Chain([1, 1, 1, 1], ["z", "y", "z", "y"]).forward([[0.4, -0.3, 0.5, 0.2]])
    >>> res = approximate(X, Chain([2, 2], ["z", "y"]))
    >>> res.q.round(6).tolist(), round(float(res.f[0]), 6)
    ([[0.604032, -0.333016]], 0.28254)
    """
    ic = input_chain(input_joints, input_parents, drift_tol)
    pairs = correspondence_pairs(ic.parents, ic.lengths, chain, leaf_map)
    obj = Objective(chain, pairs, ic.parents, distance)
    use_ms = (method == "lm") if multistart is None else bool(multistart)
    tracker = Tracker(obj, method, sweeps, max_iter, use_ms, n_starts, jump_factor, jump_abs, seed)
    R, p = _bases(chain, ic, base)
    T, m = ic.joints.shape[0], chain.dof
    start = np.zeros(m) if q0 is None else np.asarray(q0, float).reshape(m)
    if block and use_ms and T > 2 * block:
        q, f, iters, restarted = _blocked(tracker, ic, R, p, start, block, progress)
    else:
        out = _track(tracker, ic.joints, ic.valid, R, p, np.arange(T)[None], start[None], np.zeros(1), np.zeros(1, bool),
                     progress)
        q, f, iters, restarted = (a[0] for a in out)
    good = np.isfinite(f)
    joints = np.full((T, chain.n_links + 1, 3), np.nan)
    residuals = np.full((T, len(pairs)), np.nan)
    if good.any():
        arms = obj.arms(ic.joints[good])
        r, joints[good] = obj.residuals(q[good], arms, R[good] if R.ndim == 3 else R, p[good])
        residuals[good] = np.linalg.norm(r, axis=-1)
    return Approximation(q, f, joints, residuals, iters, restarted, f > flag_above, pairs, ic, method)


#: Frames solved before a block's own first frame, from a multistart, to settle onto the branch.
WARMUP = 16
#: Largest difference (rad) between a block's first frame and its predecessor's continuation.
SEAM_TOL = 1e-6


def _blocked(tracker: Tracker, ic: InputChain, R: FloatArray, p: FloatArray, q0: FloatArray,
             block: int, progress: Callable[[int, int], None] | None = None,
             ) -> tuple[FloatArray, FloatArray, NDArray[np.int64], NDArray[np.bool_]]:
    """The sequential tracking result, computed as parallel blocks checked at their seams."""
    T, m = ic.joints.shape[0], q0.size
    firsts = np.arange(0, T, block)
    begin = np.maximum(firsts - WARMUP, 0)
    end = np.minimum(firsts + block, T - 1)            # inclusive: one frame into the next block
    S = int((end - begin).max()) + 1
    schedule = np.full((firsts.size, S), -1)
    for b, (a, e) in enumerate(zip(begin, end, strict=True)):
        schedule[b, : e - a + 1] = np.arange(a, e + 1)
    B = firsts.size
    rq, rf, rit, rrs = _track(tracker, ic.joints, ic.valid, R, p, schedule, np.tile(q0, (B, 1)), np.zeros(B),
                              np.zeros(B, bool), progress)
    q = np.full((T, m), np.nan)
    f = np.full(T, np.nan)
    iters = np.zeros(T, np.int64)
    restarted = np.zeros(T, bool)
    chain = tracker.objective.output
    for b in range(B):
        off = firsts[b] - begin[b]
        if b > 0:
            cont = rq[b - 1, firsts[b] - begin[b - 1]]       # the predecessor's solution of this frame
            head = rq[b, off]
            if np.isfinite(cont).all() and np.isfinite(head).all():
                rq[b] += unwrap_to(head, cont, chain) - head  # same 2π branch as the predecessor
            both_gap = not np.isfinite(cont).any() and not np.isfinite(rq[b, off]).any()
            if not both_gap and not np.abs(rq[b, off] - cont).max() <= SEAM_TOL:
                prev = firsts[b] - 1
                has = np.isfinite(f[prev:prev + 1])
                start = q[prev] if has[0] else q0
                frames = np.arange(firsts[b], end[b] + 1)
                out = _track(tracker, ic.joints, ic.valid, R, p, frames[None], start[None],
                             np.nan_to_num(f[prev:prev + 1]), has)
                for row, new in zip((rq, rf, rit, rrs), out, strict=True):
                    row[b, off: off + frames.size] = new[0]
        n_own = min(block, T - firsts[b])
        sl = slice(firsts[b], firsts[b] + n_own)
        q[sl], f[sl], iters[sl], restarted[sl] = (row[b, off: off + n_own] for row in (rq, rf, rit, rrs))
    return q, f, iters, restarted
