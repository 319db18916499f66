"""The numpy-style Examples in the pipeline glue modules run and pass."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["grid", "views", "epipole", "tracks", "report"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    mod = importlib.import_module(f"mirrorlab.plugins.pipeline.{name}")
    res = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0 and res.attempted > 0
