"""The Examples in the retarget modules run and pass."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["chain", "correspondence", "objective", "approximate", "algorithms", "figures", "fallback"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    mod = importlib.import_module(f"mirrorlab.plugins.retarget.{name}")
    res = doctest.testmod(mod, optionflags=doctest.NORMALIZE_WHITESPACE)
    assert res.failed == 0 and res.attempted > 0
