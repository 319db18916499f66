"""Helpers shared by the test modules (import as ``from tests.support import ...``)."""

from __future__ import annotations

import atexit
import doctest
import fcntl
import importlib
import os
import shutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from tests.cli_worker import CliWorker

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
THIRDPARTY = HERE / "thirdparty"
#: Real recordings by other labs (``../shared/data`` beside the clone, never copied into it, or where
#: ``MIRRORLAB_SHARED_DATA`` says); the tests that read them are marked ``data`` and skip when it is
#: absent (see ``tests/conftest.py``).
SHARED_DATA = Path(os.environ.get("MIRRORLAB_SHARED_DATA") or REPO.parent / "shared" / "data")
#: Set to 1 (as ``.ci/run`` does) to make a missing data folder fail the data tests instead of skipping them.
REQUIRE_DATA_ENV = "MIRRORLAB_REQUIRE_DATA"


def built_once(tmp_path_factory: pytest.TempPathFactory, name: str, build: Callable[[Path], None]) -> Path:
    """A folder ``name`` filled by ``build(folder)`` once per test run, shared by pytest-xdist's workers.

    Expensive fixtures whose result is only read (an installed test plugin, the demo's session for
    the docs) are built by the first worker that needs them while the others wait on a file lock,
    instead of once per worker. Without xdist it is an ordinary temporary folder.
    """
    if "PYTEST_XDIST_WORKER" not in os.environ:
        folder = tmp_path_factory.mktemp(name)
        build(folder)
        return folder
    root = tmp_path_factory.getbasetemp().parent  # this run's base folder, above each worker's own
    folder, done = root / name, root / f"{name}.done"
    with open(root / f"{name}.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)  # a build that failed in another worker
            folder.mkdir()
            build(folder)
            done.touch()
    return folder


def assert_examples_pass(module: str) -> None:
    """The Examples in the docstrings of ``module`` (a dotted name) run and pass, and there is at least one."""
    result = doctest.testmod(importlib.import_module(module), optionflags=doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0 and result.failed == 0, result


def source_copy(dest: Path) -> Path:
    """A copy of what ``pip install .`` reads (pyproject, README, the four package folders) in ``dest``.

    Builds from a copy: setuptools writes ``build/`` into the tree it builds, which two xdist workers
    building the checkout at once would share.
    """
    dest.mkdir(parents=True, exist_ok=True)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy(REPO / name, dest / name)
    for folder in ("core", "instruments", "plugins", "sessions"):
        shutil.copytree(REPO / folder, dest / folder, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info"))
    return dest


def pip_install_target(package: Path, target: Path) -> Path:
    """``pip install --target`` a test plugin (no dependencies: mirrorlab is already installed)."""
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--target", str(target), str(package)], check=True)
    return target


def plugin_site(source: str, distribution: str, entry: str, src: Path, target: Path) -> Path:
    """Install a one-module third-party plugin: package ``<entry>_mirrorlab`` holding ``source``,
    distribution ``distribution``, entry point ``entry`` of group ``mirrorlab``; return the site dir."""
    package = f"{entry}_mirrorlab"
    (src / package).mkdir()
    (src / package / "__init__.py").write_text(source)
    (src / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=61"]\nbuild-backend = "setuptools.build_meta"\n'
        f'[project]\nname = "{distribution}"\nversion = "1.0.0"\n'
        f'[project.entry-points.mirrorlab]\n{entry} = "{package}"\n'
        f'[tool.setuptools]\npackages = ["{package}"]\n')
    return pip_install_target(src, target)


def run_cli(*args: str, sites: tuple[Path, ...] = (), cwd: Path | None = None,
            timeout: float = 120, fresh: bool = False) -> subprocess.CompletedProcess[str]:
    """Run the ``mirrorlab`` CLI (with extra site directories for third-party plugins).

    The command goes through ``mirrorlab.core.cli.main``, the console script's code path, in a
    long-lived worker process per set of ``sites`` (:mod:`tests.cli_worker`): output and exit code
    are a subprocess's, without paying the interpreter's start-up per command. ``fresh=True`` starts
    a new process instead (for what a process does at its start or end: signals, imports).
    """
    if not fresh:
        worker = _WORKERS.get(sites)
        if worker is None:
            worker = _WORKERS[sites] = CliWorker(sites=sites)
        return worker.run(*args, timeout=timeout, cwd=cwd or REPO)
    env = dict(os.environ)
    if sites:
        env["PYTHONPATH"] = os.pathsep.join([*map(str, sites), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return subprocess.run([sys.executable, "-m", "mirrorlab.core.cli", *args], capture_output=True, text=True,
                          env=env, cwd=cwd or REPO, timeout=timeout)


#: One CLI worker per set of site directories, for the whole test process.
_WORKERS: dict[tuple[Path, ...], CliWorker] = {}


@atexit.register
def _close_workers() -> None:
    for worker in _WORKERS.values():
        worker.close()


#: A recipe whose `run` step fails (the acme drift rate skips more than the 0.3 s recorded).
ACME_FAILING_RECIPE = """
[instruments.thermo]
plugin = "acme_thermometer"
simulate = true
[instruments.thermo.simulator]
clock = "FAST"

[[steps]]
action = "acquire"
seconds = 0.3

[[steps]]
action = "run"
algorithm = "acme_drift_rate"
inputs = { time = "/instruments/thermo/temperature/time", values = "/instruments/thermo/temperature/data" }
parameters = { skip = "100 s" }
"""


SMALL_SESSION = """
import sys
from mirrorlab.core import Session
with Session.create(sys.argv[1], operator="ana", description="small session for file tests") as s:
    s.add_instrument("thermo", "acme_thermometer", simulate=True, settings={"rate": 100})
    s.record(0.3)
    s.run("acme_drift_rate", {"time": "/instruments/thermo/temperature/time",
                              "values": "/instruments/thermo/temperature/data"})
    s.write_group("calibration/thermo", {"offset": 0.25}, {"description": "sensor offset, K"})
    s.write_group("truth/thermo", {"drift": 5.0, "start": [293.0, 0.1]}, {"source": "simulator"})
"""


def make_small_session(path: Path, acme_site: Path) -> Path:
    """A small closed session like the demo's: a recording (thermo/temperature in K), one result
    run, /calibration and /truth groups and a log; made in a subprocess with the acme plugin."""
    env = {**os.environ, "PYTHONPATH": str(acme_site)}
    subprocess.run([sys.executable, "-c", SMALL_SESSION, str(path)], check=True, env=env, timeout=120)
    return path
