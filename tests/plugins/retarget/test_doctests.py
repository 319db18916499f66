"""The Examples in the retarget modules run and pass."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass

MODULES = ["chain", "correspondence", "objective", "approximate", "algorithms", "figures", "fallback"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    assert_examples_pass(f"mirrorlab.plugins.retarget.{name}")
