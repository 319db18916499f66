"""docs/mechanisms.md is executable: its Python block runs and every console command succeeds."""

from __future__ import annotations

import re
import shlex

from tests.support import REPO, run_cli

DOC = (REPO / "docs" / "mechanisms.md").read_text()


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC, flags=re.S)


def test_python_block_runs_and_prints_the_documented_values(capsys) -> None:
    (code,) = _blocks("python")
    exec(compile(code, "docs/mechanisms.md", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "{'ground': 229.5, 'input': 99.8, 'coupler': 219.9, 'output': 132.5}", out[0]
    assert out[1] == "(2, 2) (30, 4, 2) 0.91" and out[2] == "2.65072 2.65072" and out[3] == "0.04" and out[4] == "2.0 40"


def test_console_commands_run() -> None:
    lines = [ln[2:] for block in _blocks("console") for ln in block.splitlines() if ln.startswith("$ ")]
    assert len(lines) == 6
    for line in lines:
        argv = shlex.split(line)
        assert argv[0] == "mirrorlab"
        proc = run_cli(*argv[1:], timeout=300)
        assert proc.returncode == 0, f"{line}: {proc.stderr}"
