"""What a new user met on first use (issue 19): help examples that work, complete key lists, paths,
file names and summaries that say what happened, empty recordings that do not pass as success.

Every case runs the real ``mirrorlab`` entry point in a subprocess, on real files.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.support import REPO, run_cli


def _one_line(text: str) -> str:
    return " ".join(text.split())


def test_demo_help_set_example_runs(tmp_path: Path) -> None:
    """The ``--set`` example ``mirrorlab demo --help`` gives is one the demo accepts (it used to suggest
    steps.0.seconds=2, which names the analysis recipe's first step, a `run` step without `seconds`)."""
    helptext = run_cli("demo", "--help")
    assert helptext.returncode == 0, helptext.stderr
    match = re.search(r"--set KEY=VALUE override a recipe value, e\.g\. (\S+) \(repeatable\)", _one_line(helptext.stdout))
    assert match, helptext.stdout
    out = tmp_path / "demo.h5"
    proc = run_cli("demo", "--set", match.group(1), "--out", str(out), "--no-progress", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert out.is_file()


def test_unknown_step_key_lists_every_key_of_every_step_kind(tmp_path: Path) -> None:
    """A misspelt key of a step names every key that step takes: ``action``, its parameters and its
    nested tables (a `run` step listed only `algorithm, as`, not `inputs` and `parameters`)."""
    from mirrorlab.core import ValidationError
    from mirrorlab.core.recipes import load_recipe
    from mirrorlab.core.registry import get_registry

    registry = get_registry()
    for kind in registry.names("step"):
        cls = registry.step(kind)
        recipe = tmp_path / f"{kind}.toml"
        recipe.write_text(f'[[steps]]\naction = "{kind}"\nno_such_key = 1\n')
        with pytest.raises(ValidationError) as caught:
            load_recipe(recipe, registry=registry, analysis=not cls.records)
        (problem,) = [p for p in caught.value.problems if p.key == "steps.0.no_such_key"]
        listed = problem.reason.partition("known: ")[2].split(", ")
        assert set(listed) == {"action", *(p.name for p in cls.parameters), *cls.tables}, (kind, problem.reason)


def test_run_step_unknown_key_on_the_command_line() -> None:
    proc = run_cli("run", str(REPO / "sessions" / "rssr_analysis.toml"), "--check", "--set", "steps.0.seconds=2")
    assert proc.returncode == 2
    assert proc.stderr.strip().endswith("steps.0.seconds: unknown parameter; known: action, algorithm, as, inputs, "
                                        "parameters"), proc.stderr


def test_every_recipe_path_is_relative_to_the_recipe_folder(tmp_path: Path) -> None:
    """An instrument setting (a frame folder), a step's input file and a step's output file, written
    relative in a recipe (and in a --set), are found beside the recipe whatever the working folder
    (instrument settings were relative to the working folder)."""
    import cv2
    import h5py
    import numpy as np

    from tests.support import SHARED_DATA

    lab = tmp_path / "lab"
    (lab / "frames").mkdir(parents=True)
    for k in range(3):
        frame = np.zeros((344, 512), np.uint8)
        cv2.circle(frame, (100 + 50 * k, 170), 20, 255, -1)
        cv2.imwrite(str(lab / "frames" / f"{k}.png"), frame)
    (lab / "data").symlink_to(SHARED_DATA / "mocap", target_is_directory=True)
    (lab / "out").mkdir()
    recipe = lab / "relative.toml"
    recipe.write_text('[instruments.cam]\nplugin = "film_scanner"\n[instruments.cam.settings]\nsource = "folder"\n'
                      'path = "no_such_folder"\nframe_rate = "50 Hz"\n\n'
                      '[[steps]]\naction = "acquire"\nseconds = 0\n\n'
                      '[[steps]]\naction = "retarget"\nfile = "data/markers_analogs.c3d"\n'
                      'joints = "ACRO_tip,EPICl+EPICm,STYLr+STYLu"\nlengths = "311,262"\naxes = "zyx,y"\n'
                      'name = "arm"\ncsv = "out/arm.csv"\n')
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    proc = run_cli("run", str(recipe), "--set", 'instruments.cam.settings.path="frames"', "--out",
                   str(tmp_path / "s.h5"), "--no-progress", cwd=elsewhere)
    assert proc.returncode == 0, proc.stderr
    with h5py.File(tmp_path / "s.h5", "r") as f:
        assert f["instruments/cam/frames/data"].shape[0] == 3
        assert f["retarget/arm/q"].shape[0] > 0
    assert (lab / "out" / "arm.csv").stat().st_size > 0 and list(elsewhere.iterdir()) == []


@pytest.mark.parametrize("recipe", ["retarget_live.toml", "retarget_bvh.toml"])
def test_bundled_recipes_with_files_run_from_another_folder(recipe: str, tmp_path: Path) -> None:
    """retarget_live.toml read its BVH file from the working folder: exit 1 outside the repository root.
    retarget_bvh.toml printed no summary of what it wrote."""
    short = ["--set", "steps.0.seconds=0.5"] if recipe == "retarget_live.toml" else ["--set", "steps.0.skip=2000"]
    proc = run_cli("run", str(REPO / "sessions" / recipe), *short, "--out", str(tmp_path / "s.h5"), "--no-progress",
                   cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    if recipe == "retarget_bvh.toml":  # it printed only the session line: now what it wrote, with what it did
        assert re.search(r"^  /retarget/cmu_01_01_right_arm: 12 datasets \(\S+01_01\.bvh: \d+ frames, mean f ",
                         proc.stdout, re.M), proc.stdout


EMPTY = "recorded no sample: the source delivered nothing in the time recorded"


def test_an_empty_recording_is_an_error_unless_allowed(tmp_path: Path) -> None:
    """A real-clock film scanner yields no frame in 1 s: ``record`` said ``recorded 1.0 s`` and exited 0.
    Now it is one error line and exit 1 (the file is kept); ``--allow-empty`` makes it a warning, exit 0."""
    args = ("record", "film_scanner", "--simulate", "--seconds", "1", "--lines", "64", "--no-progress")
    proc = run_cli(*args, "--out", str(tmp_path / "empty.h5"))
    assert proc.returncode == 1, proc.stderr
    (line,) = proc.stderr.splitlines()
    assert line.startswith(f"mirrorlab: error: dev {EMPTY}") and line.endswith("add --allow-empty to accept an "
                                                                                "empty recording"), line
    assert "dev/frames: 0 samples" in proc.stdout and (tmp_path / "empty.h5").is_file()
    allowed = run_cli(*args, "--out", str(tmp_path / "allowed.h5"), "--allow-empty")
    assert allowed.returncode == 0, allowed.stderr
    assert allowed.stderr.startswith(f"mirrorlab: warning: dev {EMPTY}"), allowed.stderr


def test_an_empty_recording_of_a_recipe_is_an_error_unless_allowed(tmp_path: Path) -> None:
    args = ("run", str(REPO / "sessions" / "scan_film.toml"), "--set", 'instruments.scanner.simulator.clock="REAL"',
            "--set", "steps.0.seconds=1", "--no-progress")
    proc = run_cli(*args, "--out", str(tmp_path / "empty.h5"))
    assert proc.returncode == 1, proc.stderr
    assert [line for line in proc.stderr.splitlines() if line.startswith("mirrorlab: error:")] == [
        f"mirrorlab: error: scanner {EMPTY} (e.g. a real-clock film scanner takes seconds per frame: record longer); "
        f"{tmp_path / 'empty.h5'} keeps the empty recording; add --allow-empty to accept an empty recording"]
    allowed = run_cli(*args, "--out", str(tmp_path / "allowed.h5"), "--allow-empty")
    assert allowed.returncode == 0 and f"mirrorlab: warning: scanner {EMPTY}" in allowed.stderr, allowed.stderr
