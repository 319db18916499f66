"""Static correspondence by normalised length (spec §3) and its extension to trees (spec §10).

An *input* chain or tree is given by node positions and node parents: node 0 is the root and
arm ``a`` is the segment from node ``parents[a + 1]`` to node ``a + 1`` (for a serial chain, from
``J_a`` to ``J_{a+1}``). The correspondence is a list of pairs (output node ``k``, input arm ``a``);
the evaluation function sums the squared distance of node ``k`` to arm ``a`` over the pairs.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .chain import Tree
from .errors import TopologyError

__all__ = ["normalised_positions", "serial_correspondence", "correspondence_pairs", "serial_parents", "leaf_paths"]

#: Tolerance of the tie rule s_o == s_in (normalised positions are ratios of float sums).
TIE_TOL = 1e-12


def normalised_positions(lengths: ArrayLike) -> NDArray[np.float64]:
    """Cumulative length of each joint along a chain divided by the total, ``s_0 = 0 … s_N = 1``.

    Examples
    --------
    >>> normalised_positions([1, 1, 2]).tolist()
    [0.0, 0.25, 0.5, 1.0]
    """
    ell = np.asarray(lengths, float)
    return np.concatenate([[0.0], np.cumsum(ell) / ell.sum()])


def serial_correspondence(input_lengths: ArrayLike, output_lengths: ArrayLike) -> NDArray[np.int64]:
    """Input arm ``c(k)`` of each output joint ``k = 0 … N_out`` (spec §3).

    ``c(k) = min(max{a : s_in_a <= s_o_k}, N_in - 1)``; on a tie the arm that starts at that input
    joint is taken, the base maps to arm 0 and the tip to the last arm.

    Examples
    --------
    The spec's fixtures T1 (4 → 2) and T2 (6 → 4):

    >>> serial_correspondence([1, 1, 1, 1], [2, 2]).tolist()
    [0, 2, 3]
    >>> serial_correspondence([1] * 6, [1.5] * 4).tolist()
    [0, 1, 3, 4, 5]
    """
    s_in = normalised_positions(input_lengths)
    s_o = normalised_positions(output_lengths)
    a = np.searchsorted(s_in, s_o + TIE_TOL, side="right") - 1
    return np.minimum(a, s_in.size - 2).astype(np.int64)


def serial_parents(n_nodes: int) -> NDArray[np.int64]:
    """Node parents of a serial chain with ``n_nodes`` joints: ``[-1, 0, 1, …]``."""
    return np.arange(n_nodes, dtype=np.int64) - 1


def leaf_paths(parents: ArrayLike) -> list[list[int]]:
    """Node paths from the root to every leaf of a tree given by node parents (leaves in node order).

    Examples
    --------
    >>> leaf_paths([-1, 0, 1, 1])
    [[0, 1, 2], [0, 1, 3]]
    """
    par = np.asarray(parents, int)
    inner = set(par[par >= 0].tolist())
    paths = []
    for leaf in (k for k in range(par.size) if k not in inner):
        path = [leaf]
        while par[path[-1]] >= 0:
            path.append(int(par[path[-1]]))
        paths.append(path[::-1])
    return paths


def correspondence_pairs(input_parents: ArrayLike, input_lengths: ArrayLike, output: Tree,
                         leaf_map: Sequence[int] | None = None) -> NDArray[np.int64]:
    """(output node, input arm) pairs of the evaluation function, for chains and trees.

    Parameters
    ----------
    input_parents : array_like (n_nodes,)
        Parent node of each input node (``-1`` for the root, node 0; ``parents[i] < i``).
    input_lengths : array_like (n_nodes - 1,)
        Length of input arm ``a`` (node ``parents[a+1]`` to ``a + 1``), mm (medians for measured data).
    output : Tree
        Output chain or tree.
    leaf_map : sequence of int, optional
        For each output leaf path (in leaf order) the input leaf path it copies; default: same order.

    Returns
    -------
    ndarray (P, 2)
        Unique pairs, sorted by output node. For two serial chains this is ``(k, c(k))`` for every
        output joint. On a tree each root-to-leaf output path is matched to its input path by
        normalised length along the paths; a trunk node that gets different arms on different
        paths keeps one pair per arm (spec §10, "sum of its squared distances to each assigned arm").

    Raises
    ------
    TopologyError
        If the leaf counts differ and no ``leaf_map`` is given, or the map is invalid.

    Examples
    --------
    >>> from mirrorlab.plugins.retarget.chain import Chain
    >>> correspondence_pairs([-1, 0, 1, 2, 3], [1, 1, 1, 1], Chain([2, 2], ["z", "y"])).tolist()
    [[0, 0], [1, 2], [2, 3]]
    """
    in_par = np.asarray(input_parents, int)
    ell = np.asarray(input_lengths, float)
    in_paths = leaf_paths(in_par)
    out_par = np.concatenate([[-1], output.proximal])  # node parents of the output tree
    out_paths = leaf_paths(out_par)
    if leaf_map is None:
        if len(in_paths) != len(out_paths):
            raise TopologyError(f"the input has {len(in_paths)} leaf paths and the output {len(out_paths)}; "
                                "give leaf_map (for each output leaf, the index of the input leaf it copies)")
        leaf_map = list(range(len(out_paths)))
    if len(leaf_map) != len(out_paths) or any(not 0 <= int(i) < len(in_paths) for i in leaf_map):
        raise TopologyError(f"leaf_map {list(leaf_map)} must give one input leaf index in 0..{len(in_paths) - 1} "
                            f"for each of the {len(out_paths)} output leaves")
    pairs: set[tuple[int, int]] = set()
    for out_path, i in zip(out_paths, leaf_map, strict=True):
        in_path = in_paths[int(i)]
        arms = [node - 1 for node in in_path[1:]]           # arm a ends at node a + 1
        out_lengths = output.lengths[[node - 1 for node in out_path[1:]]]
        c = serial_correspondence(ell[arms], out_lengths)
        pairs.update((node, arms[int(ck)]) for node, ck in zip(out_path, c, strict=True))
    return np.array(sorted(pairs), dtype=np.int64)
