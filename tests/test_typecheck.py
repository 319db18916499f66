"""The type check of .ci/run (``python -m tests.typecheck``): mypy runs on the package laid out as
installed, errors are compared with the baseline without line numbers, a new error or a stale
baseline entry fails, and the core may have none. Checked with real mypy on a small package laid
out like mirrorlab (``package-dir`` folders), and on the committed baseline itself."""

from __future__ import annotations

import subprocess
import sys
from collections import Counter
from pathlib import Path

import pytest

from tests import typecheck
from tests.support import REPO

PYPROJECT = """\
[tool.setuptools]
package-dir = { "mirrorlab" = "top", "mirrorlab.core" = "core", "mirrorlab.plugins" = "plugins" }

[tool.mypy]
python_version = "3.11"
"""


@pytest.fixture
def repo(tmp_path: Path) -> Path:
    """A package laid out like mirrorlab: one error in the core, two in a plugin."""
    (tmp_path / "pyproject.toml").write_text(PYPROJECT)
    for folder in ("top", "core", "plugins"):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / "__init__.py").write_text("")
    (tmp_path / "core" / "clock.py").write_text("def now() -> float:\n    return 'noon'\n")
    (tmp_path / "plugins" / "fit.py").write_text(
        "from mirrorlab.core.clock import now\n\n\ndef later() -> int:\n    return now()\n\n\n"
        "def sooner() -> int:\n    return now()\n")
    return tmp_path


def test_errors_are_found_in_the_layout_as_installed(repo: Path) -> None:
    errors = typecheck.run_mypy(repo)
    assert Counter(typecheck.normalise(e) for e in errors) == Counter({
        'mirrorlab/core/clock.py:return-value:Incompatible return value type (got "str", expected "float")': 1,
        'mirrorlab/plugins/fit.py:return-value:Incompatible return value type (got "float", expected "int")': 2,
    })
    assert all(e.startswith(("mirrorlab/core/clock.py:2: error:", "mirrorlab/plugins/fit.py:")) for e in errors)


def test_new_errors_and_stale_entries_fail_and_prune_deletes_only_stale_lines(repo: Path) -> None:
    fit = 'mirrorlab/plugins/fit.py:return-value:Incompatible return value type (got "float", expected "int")'
    baseline = repo / "baseline.txt"
    baseline.write_text(f"# plugins\n{fit}\nmirrorlab/plugins/gone.py:misc:fixed long ago\n")
    problems = typecheck.check(repo, baseline)
    assert len(problems) == 2
    new, stale = problems
    # the core's error, and the plugin's second one (the baseline lists it once): with their lines
    assert new.startswith("2 mypy error(s) not in baseline.txt") and "mirrorlab/core/clock.py:2: error:" in new
    assert "mirrorlab/plugins/fit.py:9: error:" in new and "fit.py:5:" not in new  # the first is listed
    assert stale.startswith("1 entry of baseline.txt no longer occur") and stale.endswith("gone.py:misc:fixed long ago")
    assert typecheck.check(repo, baseline, delete_stale=True) == [new]
    assert baseline.read_text() == f"# plugins\n{fit}\n"


def test_the_baseline_may_not_list_the_core(repo: Path) -> None:
    core = 'mirrorlab/core/clock.py:return-value:Incompatible return value type (got "str", expected "float")'
    fit = 'mirrorlab/plugins/fit.py:return-value:Incompatible return value type (got "float", expected "int")'
    baseline = repo / "baseline.txt"
    baseline.write_text(f"{core}\n{fit}\n{fit}\n")
    [problem] = typecheck.check(repo, baseline)
    assert problem.startswith("baseline.txt lists errors of mirrorlab.core, which must have none") and core in problem
    (repo / "core" / "clock.py").write_text("def now() -> float:\n    return 12.0\n")
    (repo / "plugins" / "fit.py").write_text("def later() -> int:\n    return 1\n")
    baseline.write_text("")
    assert typecheck.check(repo, baseline) == []


def test_line_numbers_are_not_part_of_an_entry() -> None:
    assert typecheck.normalise('mirrorlab/x.py:12:5: error: Name "f" already defined on line 3  [no-redef]') == \
        'mirrorlab/x.py:no-redef:Name "f" already defined on line N'
    with pytest.raises(ValueError, match="not a mypy error line"):
        typecheck.normalise("mirrorlab/x.py:12: note: see above")


def test_the_committed_baseline_lists_the_core_only_where_pending() -> None:
    baseline = typecheck.read_baseline(typecheck.BASELINE)
    assert typecheck.core_entries(baseline) == []
    assert all(e.startswith(("mirrorlab/plugins/", "mirrorlab/instruments/", *typecheck.CORE_PENDING)) for e in baseline)
    for path in typecheck.CORE_PENDING:  # each pending file exists; once it is gone, its entry goes too
        assert (REPO / path.removeprefix("mirrorlab/")).is_file()


def test_ci_runs_the_check_after_the_import_contracts() -> None:
    ci = (REPO / ".ci" / "run").read_text()
    assert ci.index("lint-imports") < ci.index("-m tests.typecheck")
    out = subprocess.run([sys.executable, "-m", "tests.typecheck", "--help"], cwd=REPO, capture_output=True, text=True)
    assert out.returncode == 0 and "--prune" in out.stdout
