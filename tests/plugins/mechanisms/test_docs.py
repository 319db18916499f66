"""docs/mechanisms.md prints what it says (tests/test_docs.py runs its commands as written)."""

from __future__ import annotations

import ast
import re

from tests.support import REPO
from tests.tolerances import roundoff

DOC = (REPO / "docs" / "mechanisms.md").read_text()


def _blocks(lang: str) -> list[str]:
    return re.findall(rf"```{lang}\n(.*?)```", DOC, flags=re.S)


def test_python_block_runs_and_prints_the_documented_values(capsys, tmp_path, monkeypatch) -> None:
    monkeypatch.chdir(tmp_path)  # the block saves four_bar_markers.npy for the commands that follow it
    (code,) = _blocks("python")
    exec(compile(code, "docs/mechanisms.md", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    # the block prints rounded computed values (round(x, n)); the documented digits are the exact
    # result rounded, so another machine's rounding-level difference can move a printed value by at
    # most one unit of its last digit, when the result sits on a rounding boundary: compare numbers,
    # to one unit, rather than strings
    lengths = ast.literal_eval(out[0])
    assert lengths.keys() == {"ground", "input", "coupler", "output"}, out[0]
    for k, v in {"ground": 229.5, "input": 99.8, "coupler": 219.9, "output": 132.5}.items():
        assert _one_unit(lengths[k], v, 0.1), out[0]
    assert out[1].startswith("(2, 2) (30, 4, 2) ") and _one_unit(float(out[1].split()[-1]), 0.91, 0.01), out[1]
    swept, astroid = (float(x) for x in out[2].split())
    assert _one_unit(swept, 2.65072, 1e-5) and _one_unit(astroid, 2.65072, 1e-5), out[2]
    assert _one_unit(float(out[3]), 0.04, 1e-3), out[3]
    ratio, crossings = out[4].split()
    assert _one_unit(float(ratio), 2.0, 0.01) and crossings == "40", out[4]


def _one_unit(printed: float, documented: float, unit: float) -> bool:
    """``printed`` is ``documented`` or one ``unit`` of its last digit away (plus the decimals' parse)."""
    return abs(printed - documented) <= unit + roundoff(scale=abs(documented), ops=2)
