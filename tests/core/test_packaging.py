"""Packaging: every sub-package is listed, a built wheel (non-editable install) contains all code, and
``python`` started beside a clone named ``mirrorlab`` imports the installed package, not the clone (issue 19)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tomllib
import zipfile
from pathlib import Path

import pytest

from tests.support import REPO, source_copy

#: import package -> source folder; ``mirrorlab`` itself is a regular package whose ``__init__.py`` is in core/_mirrorlab
FOLDERS = {"mirrorlab": "core/_mirrorlab", "mirrorlab.core": "core", "mirrorlab.instruments": "instruments",
           "mirrorlab.plugins": "plugins", "mirrorlab.sessions": "sessions"}
TOP_FOLDERS = ("core", "instruments", "plugins", "sessions")


def _installed(source: Path) -> str:
    """Where a file of the source tree lands in an install: below the deepest mapped folder that holds it."""
    package, folder = max(((p, f) for p, f in FOLDERS.items() if source.is_relative_to(REPO / f)),
                          key=lambda item: len(Path(item[1]).parts))
    return "/".join([*package.split("."), *source.relative_to(REPO / folder).parts])


def _sources(pattern: str) -> list[Path]:
    return [p for folder in TOP_FOLDERS for p in (REPO / folder).rglob(pattern)]


def _source_packages() -> set[str]:
    return {_installed(init).removesuffix("/__init__.py").replace("/", ".") for init in _sources("__init__.py")}


def test_every_subpackage_is_listed_in_pyproject() -> None:
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"] == FOLDERS
    assert set(config["packages"]) == _source_packages()


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
                    "-w", str(out), str(source_copy(tmp_path_factory.mktemp("source")))], check=True)
    return next(out.glob("mirrorlab-*.whl"))


def _plugin_modules() -> set[str]:
    """Every built-in plugin module: each ``plugin.py`` of an instrument or algorithm package."""
    return {f"mirrorlab.{folder}.{p.parent.name}.plugin" for folder in ("plugins", "instruments")
            for p in (REPO / folder).glob("*/plugin.py")}


def test_wheel_contains_every_module(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {_installed(p) for p in _sources("*.py")}
    assert expected <= names, sorted(expected - names)[:10]
    assert "mirrorlab/__init__.py" in names, "mirrorlab must be a regular package (see pyproject.toml)"
    assert not any(n.startswith("mirrorlab/core/_mirrorlab/") for n in names)
    for recipe in ("rssr_acquire.toml", "rssr_analysis.toml"):
        assert f"mirrorlab/sessions/{recipe}" in names, "mirrorlab demo needs its recipes as package data"
    entry_points = next(n for n in names if n.endswith("entry_points.txt"))
    text = zipfile.ZipFile(wheel).read(entry_points).decode()
    assert "mirrorlab = mirrorlab.core.cli:main" in text and "[pytest11]" in text
    # the built-in plugins are entry points of this distribution, each naming a module of the wheel
    group = text.split("[mirrorlab]", 1)[1].split("\n[", 1)[0]
    targets = dict(line.split(" = ") for line in group.strip().splitlines())
    assert _plugin_modules() | {"mirrorlab.core.steps"} == set(targets.values())
    for module in targets.values():
        path = module.replace(".", "/")
        assert f"{path}.py" in names or f"{path}/__init__.py" in names, module


@pytest.fixture(scope="session")
def dependencies(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """This venv's site dir without mirrorlab: a folder of links to everything else it holds. Whether the test run's
    own mirrorlab is editable (a developer's) or a wheel (CI's), the venvs below must see only the one they install;
    .pth files stay off because the folder is added as a plain path, not a site dir."""
    where = tmp_path_factory.mktemp("dependencies")
    for entry in Path(sysconfig.get_paths()["purelib"]).iterdir():
        if not entry.name.lower().startswith(("mirrorlab", "__editable__")) and entry.suffix != ".pth":
            (where / entry.name).symlink_to(entry, target_is_directory=entry.is_dir())
    return where


def _venv(where: Path, dependencies: Path, *install: str) -> tuple[Path, Path]:
    """A venv (its python and site dir) with ``pip install --target <site> *install`` of mirrorlab alone; the
    dependencies come from ``dependencies`` (see the fixture) as a plain path."""
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(where)], check=True)
    purelib = Path(sysconfig.get_paths(vars={"base": str(where), "platbase": str(where)})["purelib"])
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation", "--target",
                    str(purelib), *install], check=True, capture_output=True)
    (purelib / "_dependencies.pth").write_text(f"{dependencies}\n")
    return where / "bin" / "python", purelib


def _probe(python: Path, cwd: Path) -> dict:
    """What ``python -c`` started in ``cwd`` imports as mirrorlab, and the built-in plugins it discovers."""
    probe = ("import json, mirrorlab, mirrorlab.core, mirrorlab.plugins\nfrom mirrorlab.core.registry import Registry\n"
             "r = Registry(entry_points=False)\n"
             "print(json.dumps({'init': mirrorlab.__file__, 'core': mirrorlab.core.__file__,"
             " 'where': list(mirrorlab.plugins.__path__), 'broken': [p.name for p in r.broken],"
             " 'plugins': sorted(r.plugins), 'algorithms': r.names('algorithm'), 'instruments': r.names('instrument')}))")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    return json.loads(subprocess.run([str(python), "-c", probe], capture_output=True, text=True, env=env, cwd=cwd,
                                     check=True).stdout)


def _assert_builtins(found: dict) -> None:
    assert found["broken"] == [] and "film_scanner" in found["instruments"]
    assert {"detect_markers", "lab_survey", "retarget", "four_bar", "track"} <= set(found["algorithms"])
    assert len(found["plugins"]) == 1 + len(_plugin_modules())


@pytest.fixture
def clone(tmp_path: Path) -> Path:
    """A clone-like folder named ``mirrorlab`` (what ``git clone`` makes), inside ``tmp_path/work``."""
    where = tmp_path / "work" / "mirrorlab"
    for name in ("pyproject.toml", "README.md"):
        where.mkdir(parents=True, exist_ok=True)
        shutil.copy(REPO / name, where / name)
    for folder in TOP_FOLDERS:
        shutil.copytree(REPO / folder, where / folder, ignore=shutil.ignore_patterns("__pycache__"))
    return where


def test_fresh_non_editable_install_finds_the_builtins(wheel: Path, dependencies: Path, tmp_path: Path) -> None:
    """A venv with the wheel installed (not the editable checkout) discovers every built-in plugin from it."""
    python, purelib = _venv(tmp_path / "venv", dependencies, str(wheel))
    found = _probe(python, cwd=tmp_path)
    assert found["where"] == [str(purelib / "mirrorlab" / "plugins")], found["where"]
    _assert_builtins(found)


def test_python_beside_a_clone_imports_the_installed_package(wheel: Path, clone: Path, dependencies: Path,
                                                              tmp_path: Path) -> None:
    """``python`` started in the folder holding a clone named mirrorlab (the README's layout, ``shared/`` beside
    the clone) imports the install: a namespace ``mirrorlab`` would be assembled from the clone first."""
    python, purelib = _venv(tmp_path / "venv", dependencies, str(wheel))
    found = _probe(python, cwd=clone.parent)
    assert (found["init"], found["core"]) == (str(purelib / "mirrorlab" / "__init__.py"),
                                               str(purelib / "mirrorlab" / "core" / "__init__.py")), found
    _assert_builtins(found)


def test_editable_install_of_a_clone(clone: Path, dependencies: Path, tmp_path: Path) -> None:
    """``pip install -e`` of a clone: ``mirrorlab`` is the regular package mapped from core/_mirrorlab, and the
    code is the clone's, from any folder."""
    python, _ = _venv(tmp_path / "venv", dependencies, "-e", str(clone))
    installed = (str(clone / "core" / "_mirrorlab" / "__init__.py"), str(clone / "core" / "__init__.py"))
    found = _probe(python, cwd=tmp_path)
    assert (found["init"], found["core"]) == installed, found
    _assert_builtins(found)
    # Beside the clone, the current folder comes before setuptools' editable import hook (a limitation setuptools
    # documents): mirrorlab is then a namespace of the clone's folder, which holds the same code.
    assert _probe(python, cwd=clone.parent)["core"] == installed[1]
