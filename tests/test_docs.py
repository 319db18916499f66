"""Every command and code block of README.md and docs/*.md runs as written (issue 8, items 5 and 11).

Conventions the documents follow, enforced here:

* A ```sh block holds commands, one per line (a trailing ``\\`` continues it, ``#`` starts a
  comment). Each runs with bash from the root of a clone-like folder: this checkout's
  ``sessions/*.toml`` and ``tests/thirdparty/``, ``../shared`` beside it, and ``mirrorlab``,
  ``python`` and ``pip`` from a throwaway venv that sees this checkout's venv (so ``pip install -e``
  in a document never touches the project's venv). A command meant to fail says ``(exit N)`` in
  its comment; every other command must exit 0.
* ``demo.h5`` is the demo's session under a fixed name: the README's ``mirrorlab demo --out
  demo.h5`` (:data:`DEMO_COMMAND`) runs once per module (about 15 s) and every document starts
  from a fresh copy of that folder, so documents do not depend on each other.
* A block whose first line is ``# <path>`` (e.g. ``# mirrorlab-acme/pyproject.toml``) is a file:
  it is written (blocks naming one path are joined in order) before the document's commands run.
* Any other ```python / ```py block runs as a script (``python -`` in that folder), in document
  order with the commands.
* Exempt: the README's "Quick start" blocks, exactly two (venv + ``pip install``; CI runs them).
  Blocks without a language (output, trees, usage synopses) and ```toml blocks without a path are
  data, not commands.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import sysconfig
from dataclasses import dataclass
from pathlib import Path

import pytest

from tests.support import REPO, SHARED_DATA, THIRDPARTY, built_once

DOCS = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
DEMO_COMMAND = "mirrorlab demo --out demo.h5"
FENCE = re.compile(r"^```(\w*)\s*$")
FILE_HEADER = re.compile(r"^# (?P<path>[\w.-]+(?:/[\w.-]+)*\.(?:py|toml))(?: \(continued\))?$")
EXPECT = re.compile(r"\(exit (\d+)\)")
RUNNABLE = {"sh", "python", "py"}


@dataclass
class Block:
    lang: str
    text: str
    heading: str
    line: int

    @property
    def file(self) -> str | None:
        m = FILE_HEADER.match(self.text.split("\n", 1)[0])
        return m["path"] if m else None


def blocks(doc: Path) -> list[Block]:
    """The fenced code blocks of a Markdown file, with the heading they are under."""
    found: list[Block] = []
    heading, lang, start, body = "", None, 0, []
    for n, line in enumerate(doc.read_text().splitlines(), 1):
        m = FENCE.match(line)
        if lang is None and m:
            lang, start, body = m[1], n, []
        elif lang is not None and line.rstrip() == "```":
            found.append(Block(lang, "\n".join(body), heading, start))
            lang = None
        elif lang is not None:
            body.append(line)
        elif line.startswith("#"):
            heading = line.lstrip("#").strip()
    assert lang is None, f"{doc}: unclosed code block from line {start}"
    return found


def commands(block: Block) -> list[str]:
    """The commands of a sh block (continuations joined, comment-only lines dropped)."""
    out, current = [], ""
    for raw in block.text.splitlines():
        line = raw.strip()
        if not current and (not line or line.startswith("#")):
            continue
        if line.endswith("\\"):
            current += line[:-1] + " "
            continue
        out.append(current + line)
        current = ""
    assert not current, f"line {block.line}: a continuation ends the block"
    return out


def exempt(doc: Path, doc_blocks: list[Block]) -> list[Block]:
    """The README's two quick-start blocks (CI runs them); none anywhere else."""
    if doc.name != "README.md":
        return []
    quick = [b for b in doc_blocks if b.heading == "Quick start" and b.lang in RUNNABLE]
    assert len(quick) == 2 and all("pip install" in b.text for b in quick), quick
    return quick


def doc_files(doc_blocks: list[Block]) -> dict[str, str]:
    """The files a document shows: its blocks per path (header line dropped), one blank line between."""
    parts: dict[str, list[str]] = {}
    for b in doc_blocks:
        if b.file:
            parts.setdefault(b.file, []).append(b.text.split("\n", 1)[1])
    return {name: "\n\n".join(texts) + "\n" for name, texts in parts.items()}


@dataclass
class Lab:
    base: Path        # the clone-like folder holding demo.h5
    env: dict[str, str]


def _throwaway_venv(where: Path) -> Path:
    """A venv that sees this checkout's venv (site dir added by a .pth) and has a ``mirrorlab`` script."""
    subprocess.run([sys.executable, "-m", "venv", str(where)], check=True)
    purelib = Path(sysconfig.get_paths(vars={"base": str(where), "platbase": str(where)})["purelib"])
    (purelib / "_mirrorlab_project_venv.pth").write_text(
        f"import site; site.addsitedir({sysconfig.get_paths()['purelib']!r})\n")
    script = where / "bin" / "mirrorlab"  # what pip writes for the console_scripts entry point
    # guarded like pip's: a Dask worker started with spawn imports the main script again
    script.write_text(f"#!{where / 'bin' / 'python'}\nimport sys\nfrom mirrorlab.core.cli import main\n"
                      "if __name__ == '__main__':\n    sys.exit(main())\n")
    script.chmod(0o755)
    return where


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> Lab:
    root = tmp_path_factory.mktemp("docs")
    venv = _throwaway_venv(root / "venv")  # one per worker: a document may pip install into it
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    env.update(PATH=f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}", VIRTUAL_ENV=str(venv), MPLBACKEND="Agg")

    def clone_with_demo(folder: Path) -> None:
        """The clone-like folder (recipes, test plugins, ../shared) holding the demo's session: built once
        per test run, then only copied (see :func:`run_document`)."""
        (folder / "shared").symlink_to(SHARED_DATA.parent, target_is_directory=True)
        base = folder / "clone"
        (base / "sessions").mkdir(parents=True)
        for recipe in (REPO / "sessions").glob("*.toml"):
            shutil.copy(recipe, base / "sessions")
        shutil.copytree(THIRDPARTY, base / "tests" / "thirdparty",
                        ignore=shutil.ignore_patterns("*.egg-info", "__pycache__", "build"))
        proc = _bash(DEMO_COMMAND, base, env)
        assert proc.returncode == 0, _explain(DEMO_COMMAND, base, proc)

    return Lab(built_once(tmp_path_factory, "docs-demo", clone_with_demo) / "clone", env)


def _bash(command: str, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", "-o", "pipefail", "-c", command], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=900)


def _explain(what: str, cwd: Path, proc: subprocess.CompletedProcess[str]) -> str:
    return (f"{what!r} in {cwd} exited {proc.returncode}\n--- stdout\n{proc.stdout[-3000:]}"
            f"\n--- stderr\n{proc.stderr[-3000:]}")


def run_document(doc: Path, lab: Lab) -> dict[str, subprocess.CompletedProcess[str]]:
    """Write the document's files, then run its commands and scripts in order; return the runs."""
    work = lab.base.parent / f"run-{doc.stem}"
    shutil.copytree(lab.base, work)
    doc_blocks = blocks(doc)
    skip = exempt(doc, doc_blocks)
    for name, text in doc_files(doc_blocks).items():
        (work / name).parent.mkdir(parents=True, exist_ok=True)
        (work / name).write_text(text)
    runs: dict[str, subprocess.CompletedProcess[str]] = {}
    for b in doc_blocks:
        if b in skip or b.file or b.lang not in RUNNABLE:
            continue
        if b.lang != "sh":
            proc = subprocess.run(["python", "-"], input=b.text, cwd=work, env=lab.env, capture_output=True,
                                  text=True, timeout=600)
            assert proc.returncode == 0, _explain(f"{doc.name} line {b.line} (python block)", work, proc)
            runs[f"python block at line {b.line}"] = proc
            continue
        for command in commands(b):
            if doc.name == "README.md" and command.split("#")[0].strip() == DEMO_COMMAND:
                continue  # the lab fixture ran it
            expected = EXPECT.search(command)
            proc = _bash(command, work, lab.env)
            assert proc.returncode == (int(expected[1]) if expected else 0), \
                _explain(f"{doc.name} line {b.line}: {command}", work, proc)
            runs[command.split("#")[0].strip()] = proc
    return runs


def test_readme_names_the_demo_session() -> None:
    """The README introduces demo.h5 with the command the lab fixture runs."""
    assert DEMO_COMMAND in [c.split("#")[0].strip() for b in blocks(REPO / "README.md") if b.lang == "sh"
                            for c in commands(b)]


def test_only_known_block_kinds() -> None:
    """Nothing escapes the run: every block is runnable, a file, or data without shell prompts."""
    for doc in DOCS:
        for b in blocks(doc):
            assert b.lang in RUNNABLE | {"", "toml"}, f"{doc.name} line {b.line}: ```{b.lang}"
            if b.lang == "":
                assert not any(line.startswith("$ ") for line in b.text.splitlines()), \
                    f"{doc.name} line {b.line}: a command in a plain block; put it in a ```sh block"


@pytest.mark.parametrize("doc", [pytest.param(d, marks=pytest.mark.data) if "shared/data" in d.read_text() else d
                                 for d in DOCS], ids=lambda p: p.name)
def test_document_runs_as_written(doc: Path, lab: Lab) -> None:
    runs = run_document(doc, lab)
    if doc.name == "writing-plugins.md":  # the doc's own package, installed with pip -e, is listed and conforms
        listing = runs["mirrorlab plugins"].stdout
        assert "acme_thermometer" in listing and "acme_drift_rate" in listing, listing
        conformance = next(p for c, p in runs.items() if c.startswith("python -m pytest"))
        assert " passed" in conformance.stdout and "failed" not in conformance.stdout, conformance.stdout


def test_writing_plugins_shows_the_whole_example_package() -> None:
    """docs/writing-plugins.md's file blocks are exactly tests/thirdparty/mirrorlab-acme (every file)."""
    package = THIRDPARTY / "mirrorlab-acme"
    shown = {k: v for k, v in doc_files(blocks(REPO / "docs" / "writing-plugins.md")).items()
             if k.startswith("mirrorlab-acme/")}
    actual = {f"mirrorlab-acme/{p.relative_to(package)}": p.read_text()
              for p in sorted(package.rglob("*")) if p.suffix in (".py", ".toml")
              and not {"build", "__pycache__"} & set(p.relative_to(package).parts) and "egg-info" not in str(p)}
    assert sorted(shown) == sorted(actual)
    for name, text in actual.items():
        assert shown[name] == text, f"{name}: the doc's blocks differ from the package file"
