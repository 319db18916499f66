"""Packaging: every sub-package is listed, and a built wheel (non-editable install) contains all code."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import sysconfig
import tomllib
import zipfile
from pathlib import Path

import pytest

from tests.support import REPO

FOLDERS = {"mirrorlab.core": "core", "mirrorlab.instruments": "instruments", "mirrorlab.plugins": "plugins",
           "mirrorlab.sessions": "sessions"}


def _source_packages() -> set[str]:
    found = set()
    for package, folder in FOLDERS.items():
        for init in (REPO / folder).rglob("__init__.py"):
            rel = init.parent.relative_to(REPO / folder)
            found.add(".".join([package, *rel.parts]))
    return found


def test_every_subpackage_is_listed_in_pyproject() -> None:
    config = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert config["package-dir"] == FOLDERS
    assert set(config["packages"]) == _source_packages()


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("wheel")
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
                    "-w", str(out), str(REPO)], check=True)
    return next(out.glob("mirrorlab-*.whl"))


def _plugin_modules() -> set[str]:
    """Every built-in plugin module: each ``plugin.py`` of an instrument or algorithm package."""
    return {f"mirrorlab.{folder}.{p.parent.name}.plugin" for folder in ("plugins", "instruments")
            for p in (REPO / folder).glob("*/plugin.py")}


def test_wheel_contains_every_module(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {f"mirrorlab/{folder}/{p.relative_to(REPO / folder).as_posix()}"
                for folder in FOLDERS.values() for p in (REPO / folder).rglob("*.py")}
    assert expected <= names, sorted(expected - names)[:10]
    assert not any(n.startswith("mirrorlab/__init__") for n in names), "mirrorlab must stay a namespace package"
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


def test_fresh_non_editable_install_finds_the_builtins(wheel: Path, tmp_path: Path) -> None:
    """A venv with the wheel installed (not the editable checkout) discovers every built-in plugin from it."""
    venv = tmp_path / "venv"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
    purelib = Path(sysconfig.get_paths(vars={"base": str(venv), "platbase": str(venv)})["purelib"])
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(purelib),
                    str(wheel)], check=True)
    # the dependencies from this venv, as a plain path: its .pth files (the editable finder) stay off
    (purelib / "_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    probe = ("import json, mirrorlab.plugins\nfrom mirrorlab.core.registry import Registry\n"
             "r = Registry(entry_points=False)\n"
             "print(json.dumps({'where': list(mirrorlab.plugins.__path__), 'broken': [p.name for p in r.broken],"
             " 'plugins': sorted(r.plugins), 'algorithms': r.names('algorithm'), 'instruments': r.names('instrument')}))")
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    out = subprocess.run([str(venv / "bin" / "python"), "-c", probe], capture_output=True, text=True, env=env,
                         cwd=tmp_path, check=True).stdout
    found = json.loads(out)
    assert found["where"] == [str(purelib / "mirrorlab" / "plugins")], found["where"]
    assert found["broken"] == [] and "film_scanner" in found["instruments"]
    assert {"detect_markers", "lab_survey", "retarget", "four_bar", "track"} <= set(found["algorithms"])
    assert len(found["plugins"]) == 1 + len(_plugin_modules())
