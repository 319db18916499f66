"""The numpy-style Examples in the pairing modules run and pass."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass

MODULES = ["epipole", "pair", "regions"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    assert_examples_pass(".".join(filter(None, ["mirrorlab.plugins.pairing", name])))
