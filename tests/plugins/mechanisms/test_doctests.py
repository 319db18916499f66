"""The numpy-style Examples in the mechanisms modules run and pass."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass

MODULES = ["grouping", "planar", "fourbar", "synthetic", "swept", "walls", "joints", "steps", "figures"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    assert_examples_pass(f"mirrorlab.plugins.mechanisms.{name}")
