"""The Examples in the core's docstrings run and pass (the Session example records a simulated scanner)."""

from __future__ import annotations

import pytest

from tests.support import assert_examples_pass

MODULES = ["mirrorlab.core.params", "mirrorlab.core.session", "mirrorlab.core.store.reader", "mirrorlab.core.store.session_file",
           "mirrorlab.core.cli.options",
           "mirrorlab.core.batch.chunks", "mirrorlab.core.digests", "mirrorlab.core.batch.options", "mirrorlab.core.tui.latest",
           "mirrorlab.core.tui.ticks", "mirrorlab.core.algorithms", "mirrorlab.core.figures",
           "mirrorlab.core.devices.simulator", "mirrorlab.core.devices.streaming", "mirrorlab.core.devices.wire"]


@pytest.mark.parametrize("name", MODULES)
def test_module_examples(name: str) -> None:
    assert_examples_pass(name)
