"""Packaging: every sub-package is listed, and a built wheel (non-editable install) contains all code."""

from __future__ import annotations

import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

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


def test_wheel_contains_every_module(tmp_path: Path) -> None:
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--quiet", "--no-deps", "--no-build-isolation",
                    "-w", str(tmp_path), str(REPO)], check=True)
    wheel = next(tmp_path.glob("mirrorlab-*.whl"))
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
