"""Fixtures of the photogrammetry tests: the validation script of docs/validation and the thesis's mirror scene."""

from __future__ import annotations

import importlib.util
from types import ModuleType

import pytest
from mirrorlab.plugins.photogrammetry.sensitivity import MirrorScene

from tests.support import REPO


@pytest.fixture(scope="module")
def validation() -> ModuleType:
    """``docs/validation/photogrammetry_thesis.py`` loaded as a module (it is a script, not a package module)."""
    spec = importlib.util.spec_from_file_location("photogrammetry_thesis", REPO / "docs" / "validation"
                                                  / "photogrammetry_thesis.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.fixture(scope="module")
def scene() -> MirrorScene:
    """The thesis's mirror set-up (§3)."""
    return MirrorScene.thesis()
