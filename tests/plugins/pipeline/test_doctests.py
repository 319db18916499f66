"""The numpy-style Examples in the pipeline glue modules run and pass."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass

MODULES = ["grid", "views", "epipole", "tracks", "report"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    assert_examples_pass(f"mirrorlab.plugins.pipeline.{name}")
