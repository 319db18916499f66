"""The type check of ``.ci/run``: mypy over the ``mirrorlab`` package, against a baseline that may only shrink.

Run from the repository root::

    python -m tests.typecheck            # exit 0: no error outside the baseline, no stale baseline entry
    python -m tests.typecheck --prune    # also delete the baseline entries that no longer occur

Rules: no error in ``mirrorlab.core`` (but in the files of :data:`CORE_PENDING`, for now); elsewhere
(plugins, instruments) only the errors listed in ``tests/mypy_baseline.txt``. An error not listed
fails the check, and so does a listed one that no longer occurs (delete its line: the baseline only
shrinks). Errors are compared as ``<file>:<error code>:<message>``, without line numbers, so that
an edit elsewhere in a file leaves the baseline alone; a line listed twice stands for two errors.

mypy cannot read the ``package-dir`` mapping of pyproject.toml (``mirrorlab.core`` is the folder
``core``...): the check lays the package out as it is installed, with symbolic links to the
folders, under ``.mypy_cache/`` of the repository, and runs mypy there with the repository's
configuration (``[tool.mypy]`` in pyproject.toml) and the Python that runs this module.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tomllib
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
BASELINE = REPO / "tests" / "mypy_baseline.txt"
#: Files of mirrorlab.core whose errors the baseline may still list, each with the reason.
CORE_PENDING: dict[str, str] = {}  # core files allowed baseline errors for now (none: keep it that way)
_ERROR = re.compile(r"^(?P<file>[^:\s]+\.pyi?):(?P<line>\d+):(?:\d+:)? error: (?P<message>.*?)\s+\[(?P<code>[a-z0-9-]+)\]$")


def package_tree(repo: Path, dest: Path) -> str:
    """Lay out the package of ``repo`` as installed (``package-dir`` of its pyproject.toml) in ``dest``
    with symbolic links; return the top-level package's name."""
    mapping: dict[str, str] = tomllib.loads((repo / "pyproject.toml").read_text())["tool"]["setuptools"]["package-dir"]
    top = min(mapping, key=len)
    root = dest / top
    root.mkdir(parents=True, exist_ok=True)
    for link in root.iterdir():  # a stale layout of an earlier run
        if link.is_symlink():
            link.unlink()
    for path in (repo / mapping[top]).glob("*.py"):
        (root / path.name).symlink_to(path)
    for name, folder in mapping.items():
        if name != top:
            (dest / name.replace(".", "/")).symlink_to(repo / folder, target_is_directory=True)
    return top


def run_mypy(repo: Path) -> list[str]:
    """mypy's error lines for the package of ``repo`` (``<file>:<line>: error: <message>  [<code>]``).

    Raises
    ------
    RuntimeError
        mypy did not run to the end (a configuration error, a crash): its output.
    """
    work = repo / ".mypy_cache"  # mypy's own folder: git ignores it, and its cache makes the next run fast
    top = package_tree(repo, work / "package")
    out = subprocess.run([sys.executable, "-m", "mypy", "--config-file", str(repo / "pyproject.toml"),
                          "--cache-dir", str(work), "--no-error-summary", "--no-pretty", "--show-error-codes",
                          "--hide-error-context", "-p", top],
                         cwd=work / "package", capture_output=True, text=True)
    if out.returncode not in (0, 1) or out.stderr.strip():
        raise RuntimeError(f"mypy exited with {out.returncode}:\n{out.stdout}{out.stderr}")
    return [line for line in out.stdout.splitlines() if " error: " in line]


def normalise(line: str) -> str:
    """``<file>:<code>:<message>`` of one mypy error line: no line numbers, also none in the message.

    >>> normalise('mirrorlab/x.py:12: error: Name "f" already defined on line 3  [no-redef]')
    'mirrorlab/x.py:no-redef:Name "f" already defined on line N'
    """
    m = _ERROR.match(line)
    if m is None:
        raise ValueError(f"not a mypy error line: {line!r}")
    message = re.sub(r"\bline \d+\b", "line N", m["message"])
    return f"{m['file']}:{m['code']}:{message}"


def read_baseline(path: Path) -> Counter[str]:
    """The baseline's entries (``#`` comments and blank lines aside), with their counts."""
    lines = path.read_text().splitlines() if path.exists() else []
    return Counter(line for line in lines if line.strip() and not line.startswith("#"))


def core_entries(baseline: Counter[str]) -> list[str]:
    """Baseline entries of mirrorlab.core outside :data:`CORE_PENDING` (there must be none)."""
    return sorted(e for e in baseline if e.startswith("mirrorlab/core/") and e.split(":", 1)[0] not in CORE_PENDING)


def compare(errors: list[str], baseline: Counter[str]) -> tuple[list[str], list[str]]:
    """(error lines not in the baseline, baseline entries that no longer occur), each once per occurrence."""
    left = baseline.copy()
    new = []
    for line in errors:
        key = normalise(line)
        if left[key] > 0:
            left[key] -= 1
        else:
            new.append(line)
    return new, sorted(left.elements())


def prune(path: Path, stale: list[str]) -> None:
    """Delete one baseline line per stale entry, keeping comments and order."""
    drop = Counter(stale)
    kept = []
    for line in path.read_text().splitlines():
        if drop[line] > 0:
            drop[line] -= 1
        else:
            kept.append(line)
    path.write_text("\n".join(kept) + "\n")


def check(repo: Path = REPO, baseline_path: Path = BASELINE, delete_stale: bool = False) -> list[str]:
    """Run the check; return its problems, one paragraph each (none: it passes)."""
    baseline = read_baseline(baseline_path)
    new, stale = compare(run_mypy(repo), baseline)
    name = baseline_path.relative_to(repo) if baseline_path.is_relative_to(repo) else baseline_path
    problems = []
    if new:
        problems.append(f"{len(new)} mypy error(s) not in {name}; fix them (mirrorlab.core must have none, "
                        "and the baseline only shrinks):\n" + "\n".join(new))
    if stale and delete_stale:
        prune(baseline_path, stale)
    elif stale:
        problems.append(f"{len(stale)} entr{'y' if len(stale) == 1 else 'ies'} of {name} no longer occur: delete "
                        "these lines (or run python -m tests.typecheck --prune):\n" + "\n".join(stale))
    core = core_entries(baseline)
    if core:
        problems.append(f"{name} lists errors of mirrorlab.core, which must have none: fix them and delete the "
                        "lines:\n" + "\n".join(core))
    return problems


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m tests.typecheck", description=__doc__.split("\n\n")[0])
    parser.add_argument("--prune", action="store_true", help="delete the baseline entries that no longer occur")
    args = parser.parse_args(argv)
    problems = check(delete_stale=args.prune)
    for problem in problems:
        print(problem, end="\n\n", file=sys.stderr)
    if not problems:
        print(f"mypy: no error outside {BASELINE.relative_to(REPO)} ({sum(read_baseline(BASELINE).values())} left there)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
