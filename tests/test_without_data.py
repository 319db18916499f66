"""A clone without ``../shared/data`` collects the whole suite and skips exactly the data tests,
with a reason naming the folder; under ``MIRRORLAB_REQUIRE_DATA=1`` (CI) they fail instead."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support import REPO

pytestmark = pytest.mark.slow


def _pytest(*args: str, data: Path, require: bool = False) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MIRRORLAB_SHARED_DATA": str(data)}
    env.pop("MIRRORLAB_REQUIRE_DATA", None)
    if require:
        env["MIRRORLAB_REQUIRE_DATA"] = "1"
    return subprocess.run([sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-p", "no:xdist", *args],
                          cwd=REPO, env=env, capture_output=True, text=True, timeout=600)


def test_the_whole_suite_collects_without_the_data(tmp_path: Path) -> None:
    proc = _pytest("--collect-only", "-q", data=tmp_path / "absent")
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert " tests collected" in proc.stdout or "tests collected" in proc.stdout


def test_data_tests_skip_naming_the_folder_and_fail_when_required(tmp_path: Path) -> None:
    absent = tmp_path / "absent"
    module = "tests/plugins/kinematics/test_io.py"
    skipped = _pytest("-q", "-rs", module, data=absent)
    assert skipped.returncode == 0, skipped.stdout[-3000:]
    assert f"needs the validation data folder {absent}" in skipped.stdout and " skipped" in skipped.stdout
    required = _pytest("-q", module, data=absent, require=True)
    assert required.returncode == 1 and "MIRRORLAB_REQUIRE_DATA=1 requires it" in required.stdout, required.stdout[-3000:]
