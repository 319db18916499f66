"""The Examples in the virtual lab's docstrings run and pass (the scenes' printed values among them)."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["lab", "optics", "scenes", "truth", "motion", "render", "box_flight"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    mod = importlib.import_module(f"mirrorlab.instruments.virtual_lab.{name}")
    res = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0 and res.attempted > 0
