"""Branched chains (spec §10): a torso with two arms."""

from __future__ import annotations

import numpy as np
from mirrorlab.plugins.retarget import Objective, Tree, approximate, correspondence_pairs
from mirrorlab.plugins.retarget.solvers import multistart, start_points

from tests.plugins.retarget.optimum import optimum_bounds

# spine, right clavicle, upper arm, forearm, left clavicle, upper arm, forearm
HUMAN = Tree([1.0, 0.4, 0.6, 0.5, 0.4, 0.6, 0.5], ["zy", "z", "zy", "y", "z", "zy", "y"], [-1, 0, 1, 2, 0, 4, 5])
# spine, right arm (2 links), left arm (2 links)
ROBOT = Tree([1.0, 0.9, 0.6, 0.9, 0.6], ["zy", "zy", "y", "zy", "y"], [-1, 0, 1, 0, 3])


def node_parents(tree: Tree) -> np.ndarray:
    return np.concatenate([[-1], tree.proximal])


def motion(frames: int) -> np.ndarray:
    t = np.arange(frames)[:, None]
    return HUMAN.forward(0.5 * np.sin(0.04 * t + np.arange(HUMAN.dof)))


def test_identical_trees_are_copied_exactly() -> None:
    X = motion(30)
    res = approximate(X, HUMAN, input_parents=node_parents(HUMAN), max_iter=100)
    # f* = 0 at the input's own angles: LM's stop bounds f and the joints (tests/plugins/retarget/optimum.py)
    obj = Objective(HUMAN, res.pairs, node_parents(HUMAN))
    b = optimum_bounds(obj, res.q, obj.arms(X), np.eye(3), X[:, 0])
    assert (res.f <= b.f).all() and (np.abs(res.joints - X).max(axis=(1, 2)) <= b.joints).all()


def test_torso_with_two_arms_pairs_and_optimum() -> None:
    pairs = correspondence_pairs(node_parents(HUMAN), HUMAN.lengths, ROBOT)
    # the chest (output node 1, at 0.4 of both paths) ties with input node 1 and takes the arm starting
    # there on each path: both clavicles (spec §10, sum rule); each hand maps to its own forearm
    assert pairs.tolist() == [[0, 0], [1, 1], [1, 4], [2, 2], [3, 3], [4, 5], [5, 6]]
    X = motion(25)
    lm = approximate(X, ROBOT, input_parents=node_parents(HUMAN))
    paper = approximate(X, ROBOT, "paper", input_parents=node_parents(HUMAN))
    obj = Objective(ROBOT, lm.pairs, node_parents(HUMAN))
    best = multistart(obj, start_points(obj, 30, seed=4), obj.arms(X), np.eye(3), X[:, 0])
    # the same minimum: each solver within its bound of it (tests/plugins/retarget/optimum.py)
    arms = obj.arms(X)
    b_best = optimum_bounds(obj, best.q, arms, np.eye(3), X[:, 0]).f
    assert (np.abs(lm.f - best.f) <= optimum_bounds(obj, lm.q, arms, np.eye(3), X[:, 0]).f + b_best).all()
    assert (np.abs(paper.f - best.f) <= optimum_bounds(obj, paper.q, arms, np.eye(3), X[:, 0], method="paper").f
            + b_best).all()
    assert len(lm.jumps(0.5)) == 0



def test_a_mirrored_leaf_map_copies_worse_when_the_arms_differ() -> None:
    # ROBOT's arms are interchangeable (swapping them only permutes q, f is equal to the last bit), so
    # the mapping matters only for a robot whose arms differ: here the left one is shorter.
    robot = Tree([1.0, 0.9, 0.6, 0.6, 0.4], ["zy", "zy", "y", "zy", "y"], [-1, 0, 1, 0, 3])
    X = motion(25)
    straight = approximate(X, robot, input_parents=node_parents(HUMAN))
    swapped = approximate(X, robot, input_parents=node_parents(HUMAN), leaf_map=[1, 0])
    assert swapped.f.mean() > 1.01 * straight.f.mean()      # a structural difference, far above the solvers' bounds

