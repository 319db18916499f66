"""The Examples in the virtual lab's docstrings run and pass (the scenes' printed values among them)."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass

MODULES = ["lab", "optics", "scenes", "truth", "motion", "render", "box_flight"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    assert_examples_pass(f"mirrorlab.instruments.virtual_lab.{name}")
