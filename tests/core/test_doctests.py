"""The Examples in the core's docstrings run and pass (the Session example records a simulated scanner)."""

from __future__ import annotations

import doctest
import importlib

import pytest

MODULES = ["mirrorlab.core.params", "mirrorlab.core.session", "mirrorlab.core.store.reader", "mirrorlab.core.store.session_file",
           "mirrorlab.core.cli.options",
           "mirrorlab.core.batch.chunks", "mirrorlab.core.digests", "mirrorlab.core.batch.options", "mirrorlab.core.tui.latest",
           "mirrorlab.core.tui.ticks",
           "mirrorlab.core.devices.simulator", "mirrorlab.core.devices.streaming", "mirrorlab.core.devices.wire"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0
