"""The ``retarget`` step's ``name`` names ``/retarget/<name>``: an identifier, checked by ``run --check``."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.support import run_cli


@pytest.mark.parametrize("name", ["../truth", "/results/x", "."])
def test_the_group_name_is_an_identifier(name: str, tmp_path: Path) -> None:
    recipe = tmp_path / "r.toml"
    recipe.write_text(f'[[steps]]\naction = "retarget"\nfile = "{recipe}"\njoints = "a,b,c"\nlengths = "1,1"\n'
                      f'axes = "zyx,y"\nname = "{name}"\n')
    proc = run_cli("run", str(recipe), "--check")
    assert proc.returncode == 2
    assert f"{recipe}: steps.0.name: {name!r} is not a label" in proc.stderr
