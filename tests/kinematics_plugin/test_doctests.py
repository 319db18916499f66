"""The Examples in the kinematics adapter modules (store, algorithms, figures) run and pass."""

from __future__ import annotations

import doctest
import importlib

import pytest


@pytest.mark.parametrize("name", ["store", "algorithms", "figures"])
def test_module_examples(name):
    mod = importlib.import_module(f"mirrorlab.plugins.kinematics.{name}")
    res = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0 and res.attempted > 0
