"""Shared fixtures: the third-party test plugins installed into temporary site directories."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.support import THIRDPARTY, pip_install_target


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
