"""Shared fixtures: the validation data folder, the third-party test plugins installed into
temporary site directories; where the snapshot plugin writes its report.

Tests that read the real recordings of ``../shared/data`` are marked ``data`` (or use the
``shared_data`` fixture). Without that folder they are skipped with a reason naming it, so a clone
on its own still collects and runs the rest; with ``MIRRORLAB_REQUIRE_DATA=1`` (CI) they fail
instead, so the validation against real data cannot silently drop out.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from hypothesis import settings

from tests.support import REQUIRE_DATA_ENV, SHARED_DATA, THIRDPARTY, built_once, pip_install_target

# Property tests and fuzzers (recipes, session files, imports, replies) draw the same examples on every
# run: a seed fixed per test, so a failure in CI repeats on any machine, and each test's time is bounded
# by its own max_examples. ``HYPOTHESIS_PROFILE=explore`` draws new random examples instead.
settings.register_profile("mirrorlab", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "mirrorlab"))


def require_shared_data() -> Path:
    """The shared data folder; skips the calling test without it (fails under ``MIRRORLAB_REQUIRE_DATA=1``)."""
    if SHARED_DATA.is_dir():
        return SHARED_DATA
    reason = (f"needs the validation data folder {SHARED_DATA} (../shared/data beside the clone: real "
              "recordings by other labs, not part of the repository)")
    if os.environ.get(REQUIRE_DATA_ENV) == "1":
        pytest.fail(f"{reason}; {REQUIRE_DATA_ENV}=1 requires it")
    pytest.skip(reason)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Tests marked ``slow`` first: pytest-xdist hands out tests in this order, so the longest start
    while the many short ones fill the other workers, instead of one long test ending the run alone."""
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)


def pytest_runtest_setup(item: pytest.Item) -> None:
    if item.get_closest_marker("data") is not None:
        require_shared_data()


@pytest.fixture(scope="session")
def shared_data() -> Path:
    """``../shared/data``: real recordings by other labs (see its README)."""
    return require_shared_data()


#: pytest-textual-snapshot's default for ``--snapshot-report``: a path relative to the working
#: directory, i.e. the clone.
SNAPSHOT_REPORT_DEFAULT = "snapshot_report.html"


def pytest_configure(config: pytest.Config) -> None:
    """Declare the ``data`` marker. Write the snapshot failure report (an HTML page with the diffs
    and the whole environment) to the temporary directory instead of the clone, unless
    ``--snapshot-report`` names a place."""
    config.addinivalue_line("markers", "data: reads the real recordings of ../shared/data (skipped without it)")
    if config.getoption("--snapshot-report", default=None) == SNAPSHOT_REPORT_DEFAULT:
        config.option.snapshot_report = str(Path(tempfile.gettempdir()) / f"mirrorlab-snapshot-report-{os.getpid()}.html")


@pytest.fixture(scope="session")
def acme_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory holding the installed ``mirrorlab-acme`` distribution."""
    return built_once(tmp_path_factory, "acme-site", lambda site: pip_install_target(THIRDPARTY / "mirrorlab-acme", site))


@pytest.fixture(scope="session")
def broken_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A directory holding the deliberately broken ``mirrorlab-broken`` distribution."""
    return built_once(tmp_path_factory, "broken-site",
                      lambda site: pip_install_target(THIRDPARTY / "mirrorlab-broken", site))


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
