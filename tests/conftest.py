"""Shared fixtures: the third-party test plugins installed into temporary site directories; where the
snapshot plugin writes its report."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.support import THIRDPARTY, pip_install_target

#: pytest-textual-snapshot's default for ``--snapshot-report``: a path relative to the working
#: directory, i.e. the clone.
SNAPSHOT_REPORT_DEFAULT = "snapshot_report.html"


def pytest_configure(config: pytest.Config) -> None:
    """Write the snapshot failure report (an HTML page with the diffs and the whole environment)
    to the temporary directory instead of the clone, unless ``--snapshot-report`` names a place."""
    if config.getoption("--snapshot-report", default=None) == SNAPSHOT_REPORT_DEFAULT:
        config.option.snapshot_report = str(Path(tempfile.gettempdir()) / f"mirrorlab-snapshot-report-{os.getpid()}.html")


@pytest.fixture(scope="session")
def acme_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory holding the installed ``mirrorlab-acme`` distribution."""
    return pip_install_target(THIRDPARTY / "mirrorlab-acme", tmp_path_factory.mktemp("acme-site"))


@pytest.fixture(scope="session")
def broken_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory holding the deliberately broken ``mirrorlab-broken`` distribution."""
    return pip_install_target(THIRDPARTY / "mirrorlab-broken", tmp_path_factory.mktemp("broken-site"))


@pytest.fixture
def with_sites(monkeypatch: pytest.MonkeyPatch) -> Iterator[object]:
    """Put site directories on ``sys.path`` and rebuild the plugin registry (undone afterwards)."""
    from mirrorlab.core.registry import get_registry

    def add(*sites: Path) -> object:
        for site in sites:
            monkeypatch.syspath_prepend(str(site))
        return get_registry(refresh=True)

    yield add
    monkeypatch.undo()
    get_registry(refresh=True)
