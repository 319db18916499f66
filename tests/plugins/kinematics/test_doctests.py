"""The numpy-style Examples in the kinematics modules run and pass."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass

MODULES = ["filters", "thesis_spline", "derivatives", "rigid", "rssr", "joint_angles", "io", "synthetic"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    assert_examples_pass(f"mirrorlab.plugins.kinematics.{name}")
