"""The dependency rules of docs/ARCHITECTURE.md hold: the import-linter contracts of pyproject.toml
pass, the document states exactly those contracts, and no layer names a forbidden one in a string
(``importlib.import_module("mirrorlab.plugins...")``) or a docstring example, which import-linter
cannot see."""

from __future__ import annotations

import ast
import doctest
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from tests.support import REPO, source_copy

#: Folder of each layer -> the packages whose names its code must not hold in strings.
FORBIDDEN = {"core": ("mirrorlab.plugins", "mirrorlab.instruments"),
             "instruments": ("mirrorlab.plugins",),
             "plugins": ("mirrorlab.instruments",)}
#: Files allowed to name a forbidden package, each with the reason (none: keep it that way).
ALLOWED: dict[str, str] = {}


def _docstring_nodes(tree: ast.AST) -> set[int]:
    return {id(node.body[0].value) for node in ast.walk(tree)
            if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
            and node.body and isinstance(node.body[0], ast.Expr) and isinstance(node.body[0].value, ast.Constant)}


def _named_packages(path: Path) -> list[tuple[int, str]]:
    """(line, text) of every string that is not a docstring and every import of a docstring example."""
    tree = ast.parse(path.read_text(), str(path))
    docstrings = _docstring_nodes(tree)
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Constant) and isinstance(node.value, str)):
            continue
        if id(node) not in docstrings:
            found.append((node.lineno, node.value))
            continue
        for example in doctest.DocTestParser().get_examples(node.value):
            try:
                code = ast.parse(example.source)
            except SyntaxError:
                continue
            found += [(node.lineno + example.lineno, ast.unparse(n)) for n in ast.walk(code)
                      if isinstance(n, ast.Import | ast.ImportFrom)]
    return found


@pytest.mark.parametrize("layer", sorted(FORBIDDEN))
def test_no_layer_names_a_forbidden_package_in_a_string(layer: str) -> None:
    problems, used = [], set()
    for path in sorted((REPO / layer).rglob("*.py")):
        rel = path.relative_to(REPO).as_posix()
        for line, text in _named_packages(path):
            for name in FORBIDDEN[layer]:
                if re.search(rf"\b{re.escape(name)}\b", text):
                    if ALLOWED.get(rel) == name:
                        used.add(rel)
                    else:
                        problems.append(f"{rel}:{line}: names {name} ({text[:60]!r})")
    assert problems == [], "a layer names a package it must not import:\n" + "\n".join(problems)
    stale = [rel for rel in ALLOWED if rel.startswith(layer + "/") and rel not in used]
    assert stale == [], f"remove these allowances from tests/test_layers.py, they are no longer needed: {stale}"


#: The one package that opens session files with h5py (import-linter's contract says so for imports).
STORE = "core/store/"
#: ``.file`` attributes of the layers that are not a session's file: ``(module, receiver)``, ``*`` any module.
NOT_A_SESSION_FILE = {("*", "args"),  # the FILE argument of a command (argparse)
                      ("core/errors.py", "self")}  # Problem.file: the file a problem is in


def _file_uses(path: Path) -> list[tuple[int, str]]:
    """(line, receiver) of every ``<receiver>.file`` and ``getattr(<receiver>, "file")`` in a module."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Attribute) and node.attr == "file":
            found.append((node.lineno, ast.unparse(node.value)))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in ("getattr", "hasattr")
              and len(node.args) > 1 and isinstance(node.args[1], ast.Constant) and node.args[1].value == "file"):
            found.append((node.lineno, ast.unparse(node.args[0])))
    return found


def _layer_modules() -> list[tuple[str, Path]]:
    """(path from the repository, path) of every module of the three layers outside the store."""
    return [(path.relative_to(REPO).as_posix(), path) for layer in sorted(FORBIDDEN)
            for path in sorted((REPO / layer).rglob("*.py")) if not path.relative_to(REPO).as_posix().startswith(STORE)]


def test_no_code_outside_the_store_touches_a_session_file() -> None:
    """The TUI, the CLI, instruments and plugins read a session through its read API, never its h5py file."""
    problems = [f"{rel}:{line}: {receiver}.file" for rel, path in _layer_modules() for line, receiver in _file_uses(path)
                if ("*", receiver) not in NOT_A_SESSION_FILE and (rel, receiver) not in NOT_A_SESSION_FILE]
    assert problems == [], ("use the session's read API (read, attributes, members, tree...) instead of its h5py file:\n"
                            + "\n".join(problems))


def test_only_the_store_names_h5py_in_a_string() -> None:
    """No way around the contract "only the store imports h5py": no ``importlib.import_module("h5py")``."""
    problems = [f"{rel}:{line}: {text[:60]!r}" for rel, path in _layer_modules() for line, text in _named_packages(path)
                if re.search(r"\bh5py\b", text)]
    assert problems == [], "only mirrorlab.core.store may use h5py:\n" + "\n".join(problems)


def test_the_import_contracts_hold(tmp_path: Path) -> None:
    # import-linter maps modules to files under the package's folder: an installed copy, found first on the
    # path (an editable install's mirrorlab folder holds only its __init__)
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--target", str(tmp_path / "site"), str(source_copy(tmp_path / "source"))], check=True,
                   capture_output=True)
    env = {**os.environ, "PYTHONPATH": str(tmp_path / "site")}
    out = subprocess.run([str(Path(sys.executable).with_name("lint-imports")), "--no-cache"], cwd=REPO,
                         capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stdout + out.stderr
    assert " 0 broken" in out.stdout


def test_architecture_states_the_contracts() -> None:
    """docs/ARCHITECTURE.md lists every contract of pyproject.toml, by its name, in "Dependency rules"."""
    contracts = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["importlinter"]["contracts"]
    text = (REPO / "docs" / "ARCHITECTURE.md").read_text()
    section = text.split("## Dependency rules", 1)[1].split("\n## ", 1)[0]
    stated = re.findall(r"^\d+\. \*\*(.+?)\*\*", section, flags=re.M)
    assert stated == [c["name"] for c in contracts]
