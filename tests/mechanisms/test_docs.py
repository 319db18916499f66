"""docs/mechanisms.md prints what it says (tests/test_docs.py runs its commands as written)."""

from __future__ import annotations

import re

from tests.support import REPO

DOC = (REPO / "docs" / "mechanisms.md").read_text()


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC, flags=re.S)


def test_python_block_runs_and_prints_the_documented_values(capsys, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # the block saves four_bar_markers.npy for the commands that follow it
    (code,) = _blocks("python")
    exec(compile(code, "docs/mechanisms.md", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "{'ground': 229.5, 'input': 99.8, 'coupler': 219.9, 'output': 132.5}", out[0]
    assert out[1] == "(2, 2) (30, 4, 2) 0.91" and out[2] == "2.65072 2.65072" and out[3] == "0.04" and out[4] == "2.0 40"
