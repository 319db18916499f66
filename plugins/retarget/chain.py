"""Articulated chains and trees of revolute joints: forward kinematics and the analytic Jacobian.

Convention (spec ``retargeting.md`` §2; right-handed, intrinsic rotations): link ``j`` has length
``l_j`` along its local x axis; joint ``j`` sits at the link's proximal end and rotates it about
the ordered local axes of ``axes[j]`` (``"z"``, ``"zy"``, ``"zyx"``...)::

    R_j = R_parent(j) · Rot(a_1, q_1) · … · Rot(a_k, q_k),   J_distal(j) = J_proximal(j) + R_j (l_j, 0, 0)ᵀ

with ``R_parent = R_b`` for a link on the base. Node 0 is the base point ``p_b``; node ``j + 1`` is
the distal end of link ``j``. A serial :class:`Chain` has node ``j`` at the proximal end of link
``j`` and the tip at node ``N``. Units: lengths in mm (any consistent unit), angles in rad.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import ChainDefinitionError

__all__ = ["Tree", "Chain", "rotation", "as_base"]

FloatArray = NDArray[np.float64]

#: For a rotation about axis ``a``: the two other axes (b, c) in cyclic order, so Rot(a) turns e_b towards e_c.
_CYCLIC = {0: (1, 2), 1: (2, 0), 2: (0, 1)}
_AXIS_INDEX = {"x": 0, "y": 1, "z": 2}


def rotation(axis: str, angle: ArrayLike) -> FloatArray:
    """Rotation matrices about a coordinate axis, right-handed.

    Parameters
    ----------
    axis : {"x", "y", "z"}
        Axis of rotation.
    angle : array_like
        Angles in rad, any shape ``S``.

    Returns
    -------
    ndarray, shape S + (3, 3)

    Examples
    --------
    >>> np.round(rotation("z", np.pi / 2) @ [1.0, 0.0, 0.0], 12).tolist()
    [0.0, 1.0, 0.0]
    """
    a = np.asarray(angle, float)
    R = np.broadcast_to(np.eye(3), a.shape + (3, 3)).copy()
    return _rotate_columns(R, _AXIS_INDEX[axis], np.cos(a), np.sin(a))


def _rotate_columns(R: FloatArray, axis: int, c: FloatArray, s: FloatArray) -> FloatArray:
    """``R @ Rot(axis, θ)`` from ``c = cos θ`` and ``s = sin θ`` in place (two column updates, no matmul)."""
    b, d = _CYCLIC[axis]
    cb, cd = R[..., :, b].copy(), R[..., :, d].copy()
    c, s = c[..., None], s[..., None]
    R[..., :, b] = c * cb + s * cd
    R[..., :, d] = c * cd - s * cb
    return R


def as_base(base: Any) -> tuple[FloatArray, FloatArray]:
    """A base pose ``(R, p)`` from ``None``, a position (3,), a 4×4 transform or a pair ``(R, p)``.

    ``R`` may be (3, 3) or per frame (T, 3, 3); ``p`` (3,) or (T, 3), in mm.

    Raises
    ------
    ChainDefinitionError
        If the shapes are wrong or ``R`` is not a proper rotation (orthonormal, det +1, to 1e-6).

    Examples
    --------
    >>> R, p = as_base([1.0, 2.0, 3.0]); R.tolist() == np.eye(3).tolist(), p.tolist()
    (True, [1.0, 2.0, 3.0])
    """
    if base is None:
        return np.eye(3), np.zeros(3)
    if isinstance(base, tuple) and len(base) == 2:
        R, p = (np.asarray(x, float) for x in base)
    else:
        b = np.asarray(base, float)
        if b.shape[-1:] == (3,) and b.ndim <= 2:
            R, p = np.eye(3), b
        elif b.shape[-2:] == (4, 4):
            R, p = b[..., :3, :3], b[..., :3, 3]
        else:
            raise ChainDefinitionError(f"base must be a position (3,), a 4x4 transform or a pair (R, p); got shape {b.shape}")
    if R.shape[-2:] != (3, 3) or p.shape[-1:] != (3,):
        raise ChainDefinitionError(f"base rotation must be (…, 3, 3) and position (…, 3); got {R.shape} and {p.shape}")
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max() if R.size else 0.0
    if not np.isfinite(R).all() or err > 1e-6 or np.any(np.linalg.det(R) < 0):
        raise ChainDefinitionError("base rotation is not a proper rotation matrix (orthonormal with det +1); "
                                   "orthonormalise it, e.g. with scipy.spatial.transform.Rotation")
    return R, p


class Tree:
    """A rooted tree of links with 1–3 revolute DOF per joint (spec §2, §10).

    Parameters
    ----------
    lengths : sequence of float, length N
        Link lengths in mm, all > 0.
    axes : sequence of str, length N
        Local rotation axes of each joint in order, e.g. ``"z"``, ``"zy"``, ``"zyx"`` (1–3 of x, y, z).
    parents : sequence of int, length N
        Parent link of each link, ``-1`` for a link on the base; ``parents[j] < j``.
    base : see :func:`as_base`, optional
        Fixed base pose ``(R_b, p_b)``. ``None``: identity rotation, and :func:`~.approximate.approximate`
        places the base on the input's root joint in every frame.
    limits : array_like, shape (dof, 2), optional
        Lower and upper joint limits in rad (``±inf`` for none).

    Attributes
    ----------
    dof : int
        Number of joint angles ``m``.
    dof_link : ndarray (dof,)
        Link whose joint each angle drives.
    dof_axis : ndarray (dof,)
        Local axis index (0, 1, 2) of each angle.
    proximal : ndarray (N,)
        Node at the proximal end of each link.
    moves : ndarray (dof, N + 1) of bool
        ``moves[r, k]``: node ``k`` moves when angle ``r`` changes.
    """

    def __init__(self, lengths: ArrayLike, axes: Sequence[str], parents: Sequence[int], base: Any = None,
                 limits: ArrayLike | None = None) -> None:
        self.lengths = np.asarray(lengths, float).reshape(-1)
        N = self.lengths.size
        if N == 0:
            raise ChainDefinitionError("a chain needs at least one link")
        if not np.all(np.isfinite(self.lengths) & (self.lengths > 0)):
            bad = int(np.flatnonzero(~(self.lengths > 0))[0])
            raise ChainDefinitionError(f"link {bad} has length {self.lengths[bad]!r}; every link length must be > 0 mm")
        if isinstance(axes, str):
            raise ChainDefinitionError(f"axes must be one string per joint, e.g. ['z', 'y'], not the string {axes!r}")
        self.axes = tuple(str(a).lower() for a in axes)
        if len(self.axes) != N:
            raise ChainDefinitionError(f"{N} link lengths but {len(self.axes)} axes strings; give one per joint")
        for j, a in enumerate(self.axes):
            if not 1 <= len(a) <= 3 or any(ch not in _AXIS_INDEX for ch in a):
                raise ChainDefinitionError(f"joint {j}: axes {a!r} must be 1-3 letters of x, y, z (e.g. 'z', 'zy', 'zyx')")
        self.parents = np.asarray(parents, int).reshape(-1)
        if self.parents.size != N or np.any(self.parents >= np.arange(N)) or np.any(self.parents < -1):
            raise ChainDefinitionError(f"parents {self.parents.tolist()} must give, for each of the {N} links, "
                                       "an earlier link or -1 for the base")
        self.base = None if base is None else as_base(base)
        self.dof_link = np.array([j for j, a in enumerate(self.axes) for _ in a], int)
        self.dof_axis = np.array([_AXIS_INDEX[ch] for a in self.axes for ch in a], int)
        self.dof = int(self.dof_link.size)
        self.proximal = self.parents + 1
        subtree = np.eye(N, dtype=bool)  # subtree[i, j]: link j is in the subtree of link i
        for j in range(N):
            if self.parents[j] >= 0:
                subtree[:, j] |= subtree[:, self.parents[j]]
        node_moves = np.zeros((N, N + 1), bool)
        node_moves[:, 1:] = subtree
        self.moves = node_moves[self.dof_link]
        lim = np.tile([-np.inf, np.inf], (self.dof, 1)) if limits is None else np.asarray(limits, float)
        if lim.shape != (self.dof, 2) or np.any(lim[:, 0] >= lim[:, 1]):
            raise ChainDefinitionError(f"limits must be ({self.dof}, 2) rad with lower < upper for every angle; "
                                       f"got shape {lim.shape}")
        self.limits = lim
        # precomputed for kinematics_unchecked: the constant part of each elementary rotation, the
        # (dof, row, column) indices of its cos/sin entries, and the link loop as plain Python values
        self._unit = np.zeros((self.dof, 3, 3))
        self._unit[np.arange(self.dof), self.dof_axis, self.dof_axis] = 1.0
        bd = np.array([_CYCLIC[int(a)] for a in self.dof_axis], int).reshape(-1, 2)
        self._rot_index = (np.arange(self.dof), bd[:, 0], bd[:, 1])
        self._plan = [(j, int(self.parents[j]), int(self.proximal[j]), float(self.lengths[j]),
                       [(int(r), int(self.dof_axis[r])) for r in np.flatnonzero(self.dof_link == j)])
                      for j in range(N)]

    # -- description ----------------------------------------------------------------------------------
    @property
    def n_links(self) -> int:
        return int(self.lengths.size)

    @property
    def is_serial(self) -> bool:
        return bool(np.array_equal(self.parents, np.arange(self.n_links) - 1))

    @property
    def has_limits(self) -> bool:
        return bool(np.isfinite(self.limits).any())

    def __repr__(self) -> str:
        return (f"{type(self).__name__}(lengths={self.lengths.tolist()}, axes={list(self.axes)}, "
                f"parents={self.parents.tolist()}, dof={self.dof})")

    # -- kinematics ----------------------------------------------------------------------------------
    def _base(self, base: Any) -> tuple[FloatArray, FloatArray]:
        return as_base(base) if base is not None else (self.base if self.base is not None else as_base(None))

    def kinematics(self, q: ArrayLike, base: Any = None) -> tuple[FloatArray, FloatArray]:
        """Node positions (T, N + 1, 3) mm and world axes (T, dof, 3) of every angle for q (T, dof) rad."""
        q = np.asarray(q, float)
        if q.ndim != 2 or q.shape[1] != self.dof:
            raise ChainDefinitionError(f"joint angles must have shape (T, {self.dof}) rad, got {q.shape}")
        return self.kinematics_unchecked(q, *self._base(base))

    def kinematics_unchecked(self, q: FloatArray, R_b: FloatArray, p_b: FloatArray) -> tuple[FloatArray, FloatArray]:
        """:meth:`kinematics` for q (T, dof) and a validated base (solvers' inner loop: no checks)."""
        T = q.shape[0]
        E = np.broadcast_to(self._unit, (T,) + self._unit.shape).copy()   # elementary rotations (T, dof, 3, 3)
        c, s = np.cos(q), np.sin(q)
        r_, b_, d_ = self._rot_index
        E[:, r_, b_, b_] = c
        E[:, r_, d_, d_] = c
        E[:, r_, d_, b_] = s
        E[:, r_, b_, d_] = -s
        pos = np.empty((T, self.n_links + 1, 3))
        pos[:, 0] = p_b
        omega = np.empty((T, self.dof, 3))
        rots: list[FloatArray] = []
        R_base = np.broadcast_to(R_b, (T, 3, 3))
        for j, parent, prox, length, dofs in self._plan:
            R = R_base if parent < 0 else rots[parent]
            for r, a in dofs:
                omega[:, r] = R[:, :, a]
                R = R @ E[:, r]
            rots.append(R)
            pos[:, j + 1] = pos[:, prox] + length * R[:, :, 0]
        return pos, omega

    def forward(self, q: ArrayLike, base: Any = None) -> FloatArray:
        """Joint positions for joint angles.

        Parameters
        ----------
        q : array_like, shape (T, dof) or (dof,)
            Joint angles in rad, vectorised over frames.
        base : optional
            Base pose for these frames (see :func:`as_base`; per-frame R (T, 3, 3) and p (T, 3)
            allowed); default: the chain's own base.

        Returns
        -------
        ndarray, shape (T, N + 1, 3) or (N + 1, 3)
            Node positions in mm: base, then the distal end of every link.

        Examples
        --------
        >>> Chain([1.0, 1.0], ["z", "z"]).forward([np.pi / 2, -np.pi / 2]).round(12).tolist()
        [[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]]
        """
        qa = np.asarray(q, float)
        pos, _ = self.kinematics(qa.reshape(-1, self.dof) if qa.ndim == 1 else qa, base)
        return pos[0] if qa.ndim == 1 else pos

    def jacobian(self, q: ArrayLike, base: Any = None) -> tuple[FloatArray, FloatArray]:
        """Positions and their analytic derivatives ``∂J_k/∂q_r = ω_r × (J_k − J_joint(r))`` (spec §4).

        Parameters
        ----------
        q : array_like, shape (T, dof)
            Joint angles in rad.
        base : optional
            As in :meth:`forward`.

        Returns
        -------
        pos : ndarray, shape (T, N + 1, 3)
            Node positions in mm.
        jac : ndarray, shape (T, N + 1, 3, dof)
            mm/rad; zero where a node does not move with an angle.

        Examples
        --------
        >>> pos, jac = Chain([2.0], ["z"]).jacobian([[0.0]])
        >>> jac[0, 1, :, 0].tolist()
        [0.0, 2.0, 0.0]
        """
        pos, omega = self.kinematics(q, base)
        return pos, self.position_jacobian(pos, omega)

    def position_jacobian(self, pos: FloatArray, omega: FloatArray, nodes: NDArray[np.int64] | None = None) -> FloatArray:
        """(T, K, 3, dof) ``∂J_k/∂q_r`` from the outputs of :meth:`kinematics` (mm/rad), for ``nodes`` (default all)."""
        nodes = np.arange(pos.shape[1]) if nodes is None else nodes
        centre = pos[:, self.proximal[self.dof_link]]                    # (T, dof, 3)
        arm = pos[:, nodes, None, :] - centre[:, None, :, :]              # (T, K, dof, 3)
        w = omega[:, None, :, :]
        d = w[..., [1, 2, 0]] * arm[..., [2, 0, 1]] - w[..., [2, 0, 1]] * arm[..., [1, 2, 0]]
        return np.swapaxes(d * self.moves.T[nodes][None, :, :, None], -1, -2)

    def clip(self, q: FloatArray) -> FloatArray:
        """Angles clamped to the joint limits (rad)."""
        return np.clip(q, self.limits[:, 0], self.limits[:, 1]) if self.has_limits else q


class Chain(Tree):
    """A serial chain (spec §2): link ``j`` hangs on link ``j − 1``; nodes ``J_0 … J_N``, tip ``J_N``.

    Parameters
    ----------
    lengths : sequence of float
        Link lengths in mm (> 0).
    axes : sequence of str
        One string of local axes per joint, e.g. ``["z", "y", "z", "y"]`` or ``["zyx", "y"]``.
    base : optional
        Fixed base pose (see :func:`as_base`); ``None``: on the input's root joint, identity rotation.
    limits : array_like (dof, 2), optional
        Joint limits in rad.

    Examples
    --------
    The T1 input chain of the spec (§9):

    >>> c = Chain([1, 1, 1, 1], ["z", "y", "z", "y"])
    >>> c.dof, c.forward([0.4, -0.3, 0.5, 0.2])[-1].round(6).tolist()
    (4, [3.014405, 2.305123, 0.619241])

    A planar (2-D) chain has only ``"z"`` joints and stays in the plane z = 0:

    >>> Chain([1.0, 1.0], ["z", "z"]).is_planar
    True
    """

    def __init__(self, lengths: ArrayLike, axes: Sequence[str], base: Any = None,
                 limits: ArrayLike | None = None) -> None:
        n = np.asarray(lengths, float).reshape(-1).size
        super().__init__(lengths, axes, np.arange(n) - 1, base, limits)

    @property
    def is_planar(self) -> bool:
        """All joints turn about z and the base keeps the z axis: the chain moves in the plane z = p_b,z."""
        R = self._base(None)[0]
        return all(set(a) == {"z"} for a in self.axes) and bool(np.allclose(R[..., :, 2], [0.0, 0.0, 1.0]))
