"""Exit codes, the same in every command: 0 ok, 1 runtime failure, 2 usage or validation error.

One table over every sub-command, each case a real subprocess: an ok case, a usage case and a
runtime case wherever the command can fail at run time. A failure is one ``mirrorlab: error:``
line (or argparse's usage line plus one error line) and never a traceback.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from tests.plugins.photogrammetry.scenes import F1, grid_points
from tests.support import ACME_FAILING_RECIPE, REPO, SHARED_DATA, run_cli

C3D = SHARED_DATA / "mocap" / "markers_analogs.c3d"



@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Inputs of the table: a session with short and long series, a garbage file, CSVs, an image folder."""
    d = tmp_path_factory.mktemp("exit")
    assert run_cli("session", "new", str(d / "s.h5")).returncode == 0
    with h5py.File(d / "s.h5", "a") as f:
        f["t10"], f["v10"] = np.arange(10.0), np.sin(np.arange(30.0)).reshape(10, 3)
        f["t3"], f["v3"] = np.arange(3.0), np.zeros((3, 3))
    (d / "garbage.h5").write_text("not an HDF5 file\n")
    film, grid = grid_points()
    (d / "grid.csv").write_text("x,y,plane_x,plane_y\n" + "\n".join(
        ",".join(f"{v:.17g}" for v in (*a, *b)) for a, b in zip(film, grid)) + "\n")
    (d / "parallel.csv").write_text("frame,marker,x,y\n0,0,1,1\n0,1,1.3,1.4\n")
    (d / "too_long.csv").write_text("frame,marker,x,y\n0,0,0,0\n0,1,5,0\n")
    (d / "blank").mkdir()
    import cv2

    cv2.imwrite(str(d / "blank" / "white.png"), np.full((120, 160), 255, np.uint8))
    (d / "failing.toml").write_text(ACME_FAILING_RECIPE)
    # a recording of 512-value frames (more columns than CSV takes) for `session export`
    assert run_cli("record", "film_scanner", "--simulate", "--fast", "--seconds", "0", "--lines", "16",
                   "--scene-frames", "2", "--out", str(d / "frames.h5"), "--no-progress").returncode == 0
    (d / "filter.toml").write_text('[[steps]]\naction = "run"\nalgorithm = "filter"\n'
                                   'inputs = { time = "/t10", values = "/v10" }\n')
    return d


D = "{d}"  # replaced by the fixture's folder
CASES = [
    # command, arguments, expected exit code
    ("plugins", ["plugins"], 0),
    ("plugins", ["plugins", "--bogus"], 2),
    ("plugins", ["plugins", "show", "no_such_thing"], 2),
    ("session new", ["session", "new", f"{D}/new.h5"], 0),
    ("session new", ["session", "new"], 2),
    ("session new", ["session", "new", f"{D}/s.h5"], 1),  # exists already
    ("session info", ["session", "info", f"{D}/s.h5"], 0),
    ("session info", ["session", "info", f"{D}/missing.h5"], 2),
    ("session info", ["session", "info", f"{D}/garbage.h5"], 1),
    ("session tree", ["session", "tree", f"{D}/s.h5"], 0),
    ("session tree", ["session", "tree", f"{D}/missing.h5"], 2),
    ("session tree", ["session", "tree", f"{D}/garbage.h5"], 1),
    ("session check", ["session", "check", f"{D}/s.h5"], 0),
    ("session check", ["session", "check", f"{D}/missing.h5"], 2),
    ("session check", ["session", "check", f"{D}/garbage.h5"], 1),
    ("session close", ["session", "close", f"{D}/s.h5"], 0),
    ("session close", ["session", "close", f"{D}/missing.h5"], 2),
    ("session close", ["session", "close", f"{D}/garbage.h5"], 1),
    ("session export", ["session", "export", f"{D}/s.h5", "/t10"], 0),
    ("session export", ["session", "export", f"{D}/s.h5", "/t10", "--format", "npy"], 2),  # npy needs --out
    ("session export", ["session", "export", f"{D}/missing.h5", "/t10"], 2),
    ("session export", ["session", "export", f"{D}/garbage.h5", "/t10"], 1),
    ("session export", ["session", "export", f"{D}/s.h5", "/no_such_dataset"], 2),  # as analyze's missing dataset
    ("session export", ["session", "export", f"{D}/frames.h5", "dev/no_such_stream"], 2),
    ("session export", ["session", "export", f"{D}/frames.h5", "dev/frames"], 2),  # too wide for CSV: --format npy
    ("session export", ["session", "export", f"{D}/s.h5", "/t10", "--format", "npy", "--out", f"{D}/t10.csv"], 2),
    ("run", ["run", str(REPO / "sessions" / "scan_film.toml"), "--check"], 0),
    ("run", ["run", f"{D}/missing.toml"], 2),
    ("run", ["run", f"{D}/s.h5"], 2),  # not a TOML recipe
    ("run", ["run", f"{D}/failing.toml", "--out", f"{D}/failing.h5", "--no-progress"], 1),
    ("run", ["run", f"{D}/filter.toml", "--session", f"{D}/s.h5", "--no-progress"], 0),
    ("run", ["run", str(REPO / "sessions" / "scan_film.toml"), "--session", f"{D}/s.h5"], 2),  # records
    ("batch", ["batch", f"{D}/filter.toml", f"{D}/s.h5", "--out", f"{D}/batch", "--workers", "1", "--no-progress"], 0),
    ("batch", ["batch", f"{D}/filter.toml", f"{D}/s.h5"], 2),  # --out missing
    ("batch", ["batch", f"{D}/filter.toml", f"{D}/garbage.h5", "--out", f"{D}/batch2", "--workers", "1",
               "--retries", "0", "--no-progress"], 1),
    ("batch", ["batch", f"{D}/filter.toml", f"{D}/s.h5", "--out", f"{D}/batch3", "--scheduler", "tcp://127.0.0.1:9",
               "--no-progress"], 1),  # no scheduler there
    ("demo", ["demo", "--help"], 0),
    ("demo", ["demo", "--set", "nope.x=1"], 2),
    ("demo", ["demo", "--out", "/proc/mirrorlab-demo.h5", "--no-progress"], 1),  # cannot create the file
    ("analyze", ["analyze", "filter", f"{D}/s.h5", "--input", "time=/t10", "--input", "values=/v10"], 0),
    ("analyze", ["analyze", "filter", f"{D}/s.h5"], 2),  # inputs missing
    ("analyze", ["analyze", "filter", f"{D}/s.h5", "--input", "time=/t10", "--input", "values=/v10",
                 "--method", "nope"], 2),
    ("analyze", ["analyze", "filter", f"{D}/missing.h5", "--input", "time=/t10", "--input", "values=/v10"], 2),
    ("analyze", ["analyze", "filter", f"{D}/s.h5", "--input", "time=/t3", "--input", "values=/v3"], 1),
    ("record", ["record", "film_scanner", "--simulate", "--fast", "--seconds", "0", "--scene-frames", "2", "--lines", "16",
                "--out", f"{D}/rec.h5", "--no-progress"], 0),
    ("record", ["record", "film_scanner", "--lines", "many", "--out", f"{D}/rec2.h5"], 2),
    ("record", ["record", "film_scanner", "--port", f"{D}/no-such-port", "--out", f"{D}/rec3.h5",
                "--no-progress"], 1),
    ("simulate", ["simulate", "actuator", "--tcp", "0", "--for", "0.2"], 0),
    ("simulate", ["simulate", "no_such_instrument"], 2),
    ("simulate", ["simulate", "film_scanner", "--set", "source=folder"], 2),
    ("simulate", ["simulate", "actuator", "--pty", f"{D}/no-such-folder/tty"], 2),
    ("tui", ["tui", "--help"], 0),
    ("tui", ["tui", f"{D}/missing.toml"], 2),
    ("tui", ["tui", f"{D}/failing.toml", "--set", "nope.x=1"], 2),  # invalid recipe: named before the screen opens
    ("tui", ["tui", str(REPO / "sessions" / "scan_film.toml"), "--out", "/proc/mirrorlab-tui.h5"], 1),
    ("calibrate", ["calibrate", "--points", f"{D}/grid.csv", "--camera-center", ",".join(map(str, F1)), "--json"], 0),
    ("calibrate", ["calibrate", "--images", f"{D}/no-such-folder", "--pattern", "10x7", "--square", "25", "--json"], 2),
    ("calibrate", ["calibrate", "--images", f"{D}/blank", "--pattern", "10x7", "--json"], 2),  # --square missing
    ("calibrate", ["calibrate", "--images", f"{D}/blank", "--pattern", "10x7", "--square", "25", "--json",
                   "--no-progress"], 1),
    ("reconstruct", ["reconstruct", "--method", "parallel", "--markers", f"{D}/parallel.csv", "--lengths", "1",
                     "--signs", "1", "--magnification", "1", "--out", f"{D}/p.csv", "--no-progress"], 0),
    ("reconstruct", ["reconstruct", "--method", "parallel", "--markers", f"{D}/parallel.csv",
                     "--out", f"{D}/p.csv"], 2),  # --lengths missing
    ("reconstruct", ["reconstruct", "--method", "parallel", "--markers", f"{D}/too_long.csv", "--lengths", "1",
                     "--signs", "1", "--magnification", "1", "--out", f"{D}/p2.csv", "--no-progress"], 1),
    ("kinematics", ["kinematics", "import", str(C3D), "--session", f"{D}/k.h5"], 0),
    ("kinematics", ["kinematics", "import", f"{D}/missing.c3d", "--session", f"{D}/k2.h5"], 2),
    ("kinematics", ["kinematics", "import", f"{D}/garbage.h5", "--session", f"{D}/k3.h5", "--format", "c3d"], 1),
    ("mechanisms", ["mechanisms", "astroid", "--json"], 0),
    ("mechanisms", ["mechanisms", "four-bar", f"{D}/missing.npy"], 2),
    ("retarget", ["retarget", "run", str(C3D), "--joints", "ACRO_tip,EPICl+EPICm,STYLr+STYLu", "--lengths", "311,262",
                  "--axes", "zyx,y", "--json"], 0),
    ("retarget", ["retarget", "run", f"{D}/missing.bvh", "--joints", "a,b", "--lengths", "1", "--axes", "z"], 2),
    ("retarget", ["retarget", "run", str(C3D), "--joints", "ACRO_tip,NOPE", "--lengths", "311", "--axes", "zyx"], 1),
]


@pytest.mark.parametrize(("command", "args", "expected"),
                         [pytest.param(*case, marks=pytest.mark.data) if any(str(SHARED_DATA) in a for a in case[1])
                          else case for case in CASES],
                         ids=[f"{c}-{e}-{i}" for i, (c, _, e) in enumerate(CASES)])
def test_exit_code(command: str, args: list[str], expected: int, files: Path, acme_site: Path) -> None:
    proc = run_cli(*(a.replace(D, str(files)) for a in args), sites=(acme_site,), cwd=files)
    assert proc.returncode == expected, (proc.stdout, proc.stderr)
    assert "Traceback" not in proc.stderr
    errors = [line for line in proc.stderr.splitlines() if line.startswith("mirrorlab: error:")]
    if expected == 2:  # a validation error may list several problems, one line each
        assert errors, proc.stderr
    else:
        assert len(errors) == expected, proc.stderr


def test_every_command_is_in_the_table() -> None:
    from mirrorlab.core.cli import commands
    from mirrorlab.core.registry import Registry

    assert set(commands.command_table(Registry(entry_points=False))) == {c.split()[0] for c, _, _ in CASES}
    for name in {c.split()[0] for c, _, _ in CASES}:
        assert {e for c, _, e in CASES if c.split()[0] == name} >= {0, 2}, name


def test_exit_codes_are_documented_once_in_help() -> None:
    proc = run_cli("--help")
    assert proc.returncode == 0
    text = proc.stdout
    assert "exit codes" in text and "\n  0  ok" in text and "\n  1  runtime failure" in text
    assert "\n  2  usage or validation error" in text
