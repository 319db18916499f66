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
* Printed output (issue 19): a block without a language right after a ```sh block (nothing between
  them, or one line of prose ending in ``:`` such as "prints:") is what that block's commands print,
  each command's stdout then its stderr, compared line by line (trailing blanks ignored). ``...``
  alone on a line stands for any number of lines, and within a line for any text: use it for output
  left out and for what legitimately varies (times, temporary paths and ids, digits beyond those the
  document states).
* A clone stays clean: every file a document's commands write (besides its own file blocks) is
  matched by ``.gitignore``.
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
OUTPUT_LEAD_IN = re.compile(r"^[^#].*:$")  # "prints:" between a ```sh block and the output it shows


@dataclass(frozen=True)
class Block:
    lang: str
    text: str
    heading: str
    line: int
    lead_in: tuple[str, ...] = ()  # the non-blank lines between the previous block and this one

    @property
    def file(self) -> str | None:
        m = FILE_HEADER.match(self.text.split("\n", 1)[0])
        return m["path"] if m else None


def blocks(doc: Path) -> list[Block]:
    """The fenced code blocks of a Markdown file, with the heading they are under."""
    found: list[Block] = []
    heading, lang, start, body, prose = "", None, 0, [], []
    for n, line in enumerate(doc.read_text().splitlines(), 1):
        m = FENCE.match(line)
        if lang is None and m:
            lang, start, body = m[1], n, []
        elif lang is not None and line.rstrip() == "```":
            found.append(Block(lang, "\n".join(body), heading, start, tuple(prose)))
            lang, prose = None, []
        elif lang is not None:
            body.append(line)
        else:
            prose += [line.strip()] if line.strip() else []
            if line.startswith("#"):
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


def shown_outputs(doc_blocks: list[Block]) -> dict[Block, Block]:
    """Each ```sh block that a document follows with the output it prints."""
    return {sh: out for sh, out in zip(doc_blocks, doc_blocks[1:]) if sh.lang == "sh" and out.lang == ""
            and (not out.lead_in or (len(out.lead_in) == 1 and OUTPUT_LEAD_IN.match(out.lead_in[0])))}


ANY_LINES = r"(?:[^\n]*\n)*"


def _output_pattern(shown: list[str]) -> str:
    return "".join(ANY_LINES if line.strip() == "..." else "[^\n]*".join(map(re.escape, line.rstrip().split("..."))) + "\n"
                   for line in shown)


def _lines(printed: str) -> str:
    lines = [line.rstrip() for line in printed.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    return "".join(line + "\n" for line in lines)


def prints_as_shown(shown: str, printed: str) -> bool:
    """Whether ``printed`` is the output a document shows, line by line, ``...`` standing for any lines
    (alone on a line) or any text (within one)."""
    return re.fullmatch(_output_pattern(shown.splitlines()), _lines(printed)) is not None


def first_line_not_printed(shown: str, printed: str) -> int:
    """The index of the first line of ``shown`` that the output does not match (``len`` if the lines all match but
    the output goes on)."""
    lines = shown.splitlines()
    return next(k for k in range(len(lines), -1, -1)
                if re.fullmatch(_output_pattern(lines[:k]) + ANY_LINES, _lines(printed)))


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
    clone: frozenset[str]  # the files of the clone in it (paths relative to base), before any command ran


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
        per test run, then only copied (see :func:`run_document`); ``clone-files.txt`` lists its files
        from before the demo ran."""
        (folder / "shared").symlink_to(SHARED_DATA.parent, target_is_directory=True)
        base = folder / "clone"
        (base / "sessions").mkdir(parents=True)
        for recipe in (REPO / "sessions").glob("*.toml"):
            shutil.copy(recipe, base / "sessions")
        shutil.copytree(THIRDPARTY, base / "tests" / "thirdparty",
                        ignore=shutil.ignore_patterns("*.egg-info", "__pycache__", "build"))
        (folder / "clone-files.txt").write_text("\n".join(sorted(
            p.relative_to(base).as_posix() for p in base.rglob("*") if p.is_file())))
        proc = _bash(DEMO_COMMAND, base, env)
        assert proc.returncode == 0, _explain(DEMO_COMMAND, base, proc)

    folder = built_once(tmp_path_factory, "docs-demo", clone_with_demo)
    return Lab(folder / "clone", env, frozenset((folder / "clone-files.txt").read_text().splitlines()))


def _bash(command: str, cwd: Path, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", "-o", "pipefail", "-c", command], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=900)


def _explain(what: str, cwd: Path, proc: subprocess.CompletedProcess[str]) -> str:
    return (f"{what!r} in {cwd} exited {proc.returncode}\n--- stdout\n{proc.stdout[-3000:]}"
            f"\n--- stderr\n{proc.stderr[-3000:]}")


def workdir(doc: Path, lab: Lab) -> Path:
    return lab.base.parent / f"run-{doc.stem}"


def run_document(doc: Path, lab: Lab) -> dict[str, subprocess.CompletedProcess[str]]:
    """Write the document's files, then run its commands and scripts in order, checking the output it shows;
    return the runs."""
    work = workdir(doc, lab)
    shutil.copytree(lab.base, work)
    doc_blocks = blocks(doc)
    shown = shown_outputs(doc_blocks)
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
        printed = ""
        for command in commands(b):
            if doc.name == "README.md" and command.split("#")[0].strip() == DEMO_COMMAND:
                continue  # the lab fixture ran it
            expected = EXPECT.search(command)
            proc = _bash(command, work, lab.env)
            assert proc.returncode == (int(expected[1]) if expected else 0), \
                _explain(f"{doc.name} line {b.line}: {command}", work, proc)
            runs[command.split("#")[0].strip()] = proc
            printed += proc.stdout + proc.stderr
        if b in shown and not prints_as_shown(shown[b].text, printed):
            k = first_line_not_printed(shown[b].text, printed)
            where = (f"line {shown[b].line + 1 + k}, {shown[b].text.splitlines()[k]!r}, is not printed"
                     if k < len(shown[b].text.splitlines()) else "the output goes on (end the block with '...')")
            pytest.fail(f"{doc.name}: the output shown at line {shown[b].line} differs from what the commands of line "
                        f"{b.line} print: {where}; they print:\n{printed}")
    return runs


def untracked_outputs(doc: Path, lab: Lab) -> list[str]:
    """The files in a document's folder (after its run) that ``git status`` would list as untracked in a clone:
    not the clone's, not the document's own file blocks, not matched by the repository's ``.gitignore``."""
    work = workdir(doc, lab)
    written = {p.relative_to(work).as_posix() for p in work.rglob("*") if p.is_file()} - lab.clone \
        - set(doc_files(blocks(doc)))
    shutil.copy(REPO / ".gitignore", work / ".gitignore")  # the folder as a fresh git work tree with only that
    subprocess.run(["git", "init", "--quiet", str(work)], check=True)
    ignored = subprocess.run(["git", "-C", str(work), "-c", "core.excludesFile=/dev/null", "check-ignore", "--no-index",
                              "--stdin"], input="\n".join(sorted(written)), capture_output=True, text=True)
    assert ignored.returncode in (0, 1), ignored.stderr  # 1: none ignored
    return sorted(written - set(ignored.stdout.splitlines()))


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


def test_shown_output_wildcards(tmp_path: Path) -> None:
    """``...`` alone on a line is any lines (none too), within a line any text; everything else must match."""
    printed = "header\n  a   0.841 mm  \n  b   1.2 s\nfooter\n\n"
    for shown in ("header\n  a   0.841 mm\n  b   1.2 s\nfooter", "header\n...\nfooter", "...\nheader\n...\nfooter\n...",
                  "header\n  a   0.84... mm\n  b   ... s\nfooter"):
        assert prints_as_shown(shown, printed), shown
    for shown in ("header\n  a   0.842 mm\n  b   1.2 s\nfooter", "header\n  a   0.841 mm", "header\nfooter",
                  "header\n  a   0.84... mm\n  b   ... s\nfooter\nmore"):
        assert not prints_as_shown(shown, printed), shown
    assert first_line_not_printed("header\n  a   0.842 mm\n...", printed) == 1
    assert first_line_not_printed("header\n  a   0.841 mm", printed) == 2  # all shown, but more printed
    # the output a block shows: right after it, or after one line of prose ending in ":"
    doc = tmp_path / "doc.md"
    for between, is_output in (("", True), ("prints:\n\n", True), ("A transcript\nof the protocol:\n\n", False),
                               ("## Output\n\n", False)):
        doc.write_text(f"```sh\nx\n```\n\n{between}```\ny\n```\n")
        assert bool(shown_outputs(blocks(doc))) == is_output, between


@pytest.mark.parametrize("doc", [pytest.param(d, marks=pytest.mark.data) if "shared/data" in d.read_text() else d
                                 for d in DOCS], ids=lambda p: p.name)
@pytest.mark.slow
def test_document_runs_as_written(doc: Path, lab: Lab) -> None:
    runs = run_document(doc, lab)
    untracked = untracked_outputs(doc, lab)
    assert not untracked, f"{doc.name}: its commands write files that .gitignore does not match: {untracked}"
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
