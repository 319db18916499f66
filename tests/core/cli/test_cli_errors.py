"""How the CLI reports errors: once, on stderr, naming what is wrong; `--debug` anywhere; closed pipes."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.support import ACME_FAILING_RECIPE, REPO, run_cli


@pytest.fixture
def series(tmp_path: Path) -> Path:
    """A session with a 3-sample and a 10-sample series."""
    path = tmp_path / "s.h5"
    assert run_cli("session", "new", str(path)).returncode == 0
    with h5py.File(path, "a") as f:
        f["t3"], f["v3"] = np.arange(3.0), np.zeros((3, 3))
        f["t10"], f["v10"] = np.arange(10.0), np.zeros((10, 3))
    return path


def _mentions(proc: subprocess.CompletedProcess[str], text: str) -> int:
    return (proc.stdout + proc.stderr).count(text)


def test_failing_algorithm_is_reported_once_on_stderr(series: Path) -> None:
    proc = run_cli("analyze", "filter", str(series), "--input", "time=/t3", "--input", "values=/v3")
    assert proc.returncode == 1
    assert proc.stdout == ""
    assert proc.stderr.count("needs at least 6 samples") == 1, proc.stderr
    (line,) = proc.stderr.splitlines()
    assert line.startswith("mirrorlab: error: /results/filter/run-0001 failed: InsufficientSamples:")


def test_analyze_says_what_it_produced(series: Path) -> None:
    proc = run_cli("analyze", "filter", str(series), "--input", "time=/t10", "--input", "values=/v10")
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.startswith(f"{series}: /results/filter/run-0001: ok\n")
    for line in ("/results/filter/run-0001/filtered: (5, 3) float64", "/results/filter/run-0001/time: (5,) float64"):
        assert line in proc.stdout, proc.stdout


def test_failing_run_step_is_reported_once_on_stderr(tmp_path: Path, acme_site: Path) -> None:
    recipe = tmp_path / "failing.toml"
    recipe.write_text(ACME_FAILING_RECIPE)
    proc = run_cli("run", str(recipe), "--out", str(tmp_path / "f.h5"), sites=(acme_site,))
    assert proc.returncode == 1
    assert _mentions(proc, "need at least 2 samples after skip") == 1, proc.stderr + proc.stdout
    assert "ERROR" not in proc.stderr
    assert [ln for ln in proc.stderr.splitlines() if "error" in ln] == [proc.stderr.strip().splitlines()[-1]]


def test_misspelt_input_name_is_named_with_the_valid_names(series: Path) -> None:
    proc = run_cli("analyze", "filter", str(series), "--input", "tim=/t10", "--input", "values=/v10")
    assert proc.returncode == 2
    assert "--input tim: filter takes no input 'tim'; it takes: time, values" in proc.stderr
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize("content", [b"\x89HDF\r\n\x1a\n\x00\x00\xff\xfe binary", b"key = [unclosed\n",
                                     b"\xff\xfe\x00t\x00o\x00m\x00l"])
def test_non_toml_file_is_not_a_toml_recipe(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "file.h5"
    path.write_bytes(content)
    proc = run_cli("run", str(path), "--check")
    assert proc.returncode == 2
    (line,) = proc.stderr.splitlines()
    assert line.startswith(f"mirrorlab: error: {path}: ") and "not a TOML recipe" in line, line


def test_debug_works_after_the_subcommand(tmp_path: Path) -> None:
    missing = tmp_path / "missing.toml"
    for args in (("--debug", "run", str(missing)), ("run", str(missing), "--debug")):
        proc = run_cli(*args)
        assert proc.returncode != 0 and "Traceback" in proc.stderr and "unrecognized" not in proc.stderr
    plain = run_cli("run", str(missing))
    assert plain.returncode == 2 and "Traceback" not in plain.stderr


def test_debug_logging_is_mirrorlab_only(tmp_path: Path) -> None:
    proc = run_cli("run", str(REPO / "sessions" / "scan_film.toml"), "--check", "--debug")
    assert proc.returncode == 0
    assert not [ln for ln in proc.stderr.splitlines() if ln.startswith("DEBUG") and "mirrorlab" not in ln]


@pytest.mark.parametrize(("args", "code"), [(("plugins",), 1), (("--help",), 0), (("session", "tree", "{s}"), 1),
                                            (("plugins", "show", "filter"), 1), (("session", "export", "{s}", "/t10"), 1)])
def test_closed_pipe_ends_quietly(args: tuple[str, ...], code: int, series: Path) -> None:
    """`mirrorlab ... | head -1`: the reader has gone; no BrokenPipeError, nothing on stderr.

    Exit 1 (output lost, as in Python's own EPIPE recipe); argparse's help ignores write errors: 0.
    """
    read, write = os.pipe()
    os.close(read)  # every write of the child fails with EPIPE, as after `head` exits
    try:
        proc = subprocess.run([sys.executable, "-m", "mirrorlab.core.cli", *(a.format(s=series) for a in args)],
                              stdout=write, stderr=subprocess.PIPE, text=True, cwd=REPO, timeout=120)
    finally:
        os.close(write)
    assert proc.stderr == "" and proc.returncode == code, proc.stderr
