"""The Examples in the kinematics adapter modules (store, algorithms, figures) run and pass."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass


@pytest.mark.parametrize("name", ["store", "algorithms", "figures"])
def test_module_examples(name: str) -> None:
    assert_examples_pass(f"mirrorlab.plugins.kinematics.{name}")
