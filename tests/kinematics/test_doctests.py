"""The numpy-style Examples in the kinematics modules run and pass."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["filters", "thesis_spline", "derivatives", "rigid", "rssr", "joint_angles", "io", "synthetic"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name):
    mod = importlib.import_module(f"mirrorlab.plugins.kinematics.{name}")
    res = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0 and res.attempted > 0
