"""The evaluation function ``f`` (spec §4): squared distances of output joints to their input arms.

``f(q) = Σ_(k, a) |J_k(q) − C_a(J_k(q))|²`` over the correspondence pairs, with ``C_a(x)`` the
point of arm ``a`` closest to ``x`` (on the segment, or on its infinite line as an option). The
residual ``r = J_k − C_a`` and its analytic Jacobian ``∂r/∂q = (I − d̂d̂ᵀ) ∂J_k/∂q`` (interior of
the segment) or ``∂J_k/∂q`` (clamped to an end) feed both solvers. Everything is vectorised over
a batch of B rows (frames, or frames × starts). Units: mm, rad; ``f`` in mm².
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .chain import Tree

__all__ = ["Objective", "Arms", "DISTANCES"]

FloatArray = NDArray[np.float64]
DISTANCES = ("segment", "line")


@dataclass(frozen=True)
class Arms:
    """The input arms of the pairs for a batch of B rows (start (B, P, 3), direction, 1/|d|², unit d)."""

    start: FloatArray
    d: FloatArray
    inv_len2: FloatArray
    dhat: FloatArray

    def take(self, rows: NDArray[np.int64] | NDArray[np.bool_]) -> Arms:
        """The same arms for a subset (or repetition) of the rows."""
        return Arms(self.start[rows], self.d[rows], self.inv_len2[rows], self.dhat[rows])


class Objective:
    """Evaluation function of one output tree against one input topology.

    Parameters
    ----------
    output : Tree
        The output chain or tree.
    pairs : array_like (P, 2)
        (output node, input arm) pairs, from :func:`~.correspondence.correspondence_pairs`.
    input_parents : array_like (n_nodes,)
        Node parents of the input (arm ``a`` runs from node ``input_parents[a + 1]`` to ``a + 1``).
    distance : {"segment", "line"}
        Distance to the arm's segment (default, spec §4) or to its infinite line.

    Examples
    --------
    >>> from mirrorlab.plugins.retarget.chain import Chain
    >>> out = Chain([2.0], ["z"], base=[0.0, 0.0, 0.0])
    >>> obj = Objective(out, [[0, 0], [1, 0]], [-1, 0])
    >>> X = np.array([[[0.0, 0.0, 0.0], [0.0, 2.0, 0.0]]])        # input arm along y
    >>> float(obj.value(np.array([[0.0]]), obj.arms(X), *out.base)[0])  # tip at (2, 0, 0): 2 mm from the arm
    4.0
    """

    def __init__(self, output: Tree, pairs: ArrayLike, input_parents: ArrayLike, distance: str = "segment") -> None:
        if distance not in DISTANCES:
            raise ValueError(f"distance must be one of {DISTANCES}, got {distance!r}")
        self.output = output
        self.pairs = np.asarray(pairs, np.int64).reshape(-1, 2)
        self.node = self.pairs[:, 0]
        self.arm = self.pairs[:, 1]
        par = np.asarray(input_parents, np.int64)
        self.arm_start = par[self.arm + 1]
        self.arm_end = self.arm + 1
        self.distance = distance

    def arms(self, X: FloatArray) -> Arms:
        """Arm geometry of input positions X (B, n_nodes, 3) mm (zero-length arms must be excluded first)."""
        start = X[:, self.arm_start]
        d = X[:, self.arm_end] - start
        len2 = np.einsum("bpi,bpi->bp", d, d)
        return Arms(start, d, 1.0 / len2, d / np.sqrt(len2)[..., None])

    def _closest(self, x: FloatArray, arms: Arms) -> tuple[FloatArray, NDArray[np.bool_]]:
        rel = x - arms.start
        tau = (rel * arms.d).sum(-1) * arms.inv_len2
        if self.distance == "segment":
            interior = (tau > 0.0) & (tau < 1.0)
            tau = np.minimum(np.maximum(tau, 0.0), 1.0)
        else:
            interior = np.ones(tau.shape, bool)
        return rel - tau[..., None] * arms.d, interior

    def residuals(self, q: FloatArray, arms: Arms, R_b: FloatArray, p_b: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Residuals r (B, P, 3) mm and output node positions (B, N + 1, 3) for angles q (B, dof)."""
        pos, _ = self.output.kinematics_unchecked(q, R_b, p_b)
        r, _ = self._closest(pos[:, self.node], arms)
        return r, pos

    def value(self, q: FloatArray, arms: Arms, R_b: FloatArray, p_b: FloatArray) -> FloatArray:
        """``f`` (B,) in mm²."""
        r, _ = self.residuals(q, arms, R_b, p_b)
        return np.einsum("bpi,bpi->b", r, r)

    def residuals_jacobian(self, q: FloatArray, arms: Arms, R_b: FloatArray,
                           p_b: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Residuals (B, P, 3), their Jacobian (B, P, 3, dof) mm/rad and node positions (B, N + 1, 3)."""
        pos, omega = self.output.kinematics_unchecked(q, R_b, p_b)
        r, interior = self._closest(pos[:, self.node], arms)
        dJ = self.output.position_jacobian(pos, omega, self.node)            # (B, P, 3, dof)
        along = (arms.dhat[..., None] * dJ).sum(-2) * interior[..., None]
        return r, dJ - arms.dhat[..., None] * along[:, :, None, :], pos
