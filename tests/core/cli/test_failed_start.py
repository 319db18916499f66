"""A command that fails before its session holds anything leaves no file behind and destroys none.

Through subprocesses (the CLI) and the API: ``record`` without a port, with a wrong port or an empty
folder, ``kinematics import`` of a damaged file; ``--overwrite`` where a command creates a session,
with CLI wording on the command line and API wording for ``Session.create``.
"""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest
from mirrorlab.core import Session
from mirrorlab.core.errors import SessionError, SessionExistsError

from tests.support import SHARED_DATA, run_cli

#: A finite, fast source that needs no port: three rendered frames of the virtual RSSR scene.
VIRTUAL = ("--source", "virtual", "--scene", "rssr", "--scene-frames", "3", "--frame-rate", "100",
           "--lines", "16", "--no-progress")


def session_id(path: Path) -> str:
    with h5py.File(path, "r") as f:
        return str(f.attrs["session_id"])


def only_file(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_failed_records_leave_no_file_and_the_retry_works(tmp_path: Path) -> None:
    (tmp_path / "empty").mkdir()
    out = tmp_path / "rec.h5"
    for args in ((),                                                   # no port
                 ("--port", "/dev/mirrorlab-no-such-port"),            # a wrong port
                 ("--source", "folder", "--path", str(tmp_path / "empty"))):  # a folder without images
        failed = run_cli("record", "film_scanner", "--out", str(out), "--no-progress", *args)
        assert failed.returncode == 1 and failed.stderr.startswith("mirrorlab: error:"), failed.stderr
        assert only_file(tmp_path) == ["empty"], args  # neither the session nor a draft of it
    retry = run_cli("record", "film_scanner", "--out", str(out), "--seconds", "0", *VIRTUAL)
    assert retry.returncode == 0, retry.stderr
    with Session.open(out) as s:
        assert s.status == "closed" and s.stream("dev", "frames").data.shape == (3, 16, 512)


def test_existing_output_is_refused_with_cli_advice_and_replaced_with_overwrite(tmp_path: Path) -> None:
    out = tmp_path / "rec.h5"
    with Session.create(out, description="the old one"):
        pass
    first = session_id(out)
    again = run_cli("record", "film_scanner", "--out", str(out), "--seconds", "0", *VIRTUAL)
    assert again.returncode == 1
    assert "already exists; add --overwrite to replace it, or choose another --out" in again.stderr
    assert "overwrite=True" not in again.stderr and session_id(out) == first
    # --overwrite with a start that fails: the old session is kept as it was
    failed = run_cli("record", "film_scanner", "--out", str(out), "--overwrite", "--no-progress")
    assert failed.returncode == 1 and "no port given" in failed.stderr
    assert session_id(out) == first and only_file(tmp_path) == ["rec.h5"]
    replaced = run_cli("record", "film_scanner", "--out", str(out), "--overwrite", "--seconds", "0", *VIRTUAL)
    assert replaced.returncode == 0, replaced.stderr
    assert session_id(out) != first and only_file(tmp_path) == ["rec.h5"]


def test_recipe_run_takes_overwrite(tmp_path: Path) -> None:
    recipe = tmp_path / "virtual.toml"
    recipe.write_text('[instruments.cam]\nplugin = "film_scanner"\n[instruments.cam.settings]\n'
                      'source = "virtual"\nscene = "rssr"\nscene_frames = 2\nframe_rate = 100\nlines = 16\n'
                      '[[steps]]\naction = "acquire"\n')
    out = tmp_path / "run.h5"
    with Session.create(out, description="the old one"):
        pass
    first = session_id(out)
    again = run_cli("run", str(recipe), "--out", str(out), "--no-progress")
    assert again.returncode == 1 and "add --overwrite to replace it, or choose another --out" in again.stderr
    replaced = run_cli("run", str(recipe), "--out", str(out), "--overwrite", "--no-progress")
    assert replaced.returncode == 0, replaced.stderr
    assert session_id(out) != first and only_file(tmp_path) == ["run.h5", "virtual.toml"]


@pytest.mark.data
def test_a_failed_import_leaves_no_session_and_the_retry_works(tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.c3d"
    garbage.write_bytes(b"not a c3d file\n")
    session = tmp_path / "g.h5"
    failed = run_cli("kinematics", "import", str(garbage), "--session", str(session))
    assert failed.returncode == 1 and "garbage.c3d" in failed.stderr
    assert only_file(tmp_path) == ["garbage.c3d"]
    real = SHARED_DATA / "mocap" / "markers.trc"
    ok = run_cli("kinematics", "import", str(real), "--session", str(session))
    assert ok.returncode == 0, ok.stderr
    first = session_id(session)
    # an import into an existing session adds to it; --overwrite starts a new session instead
    replaced = run_cli("kinematics", "import", str(real), "--session", str(session), "--overwrite")
    assert replaced.returncode == 0, replaced.stderr
    assert session_id(session) != first


def test_api_wording_and_a_failed_start_in_python(tmp_path: Path) -> None:
    path = tmp_path / "s.h5"
    with pytest.raises(RuntimeError), Session.create(path) as s:
        s.events.emit("info", "test", "start", "starting")
        raise RuntimeError("the instruments could not start")
    assert not path.exists() and only_file(tmp_path) == []
    with Session.create(path, description="keep me"):
        pass
    with pytest.raises(SessionExistsError, match="already exists; pass overwrite=True to replace it") as info:
        Session.create(path)
    assert isinstance(info.value, SessionError) and info.value.path == path
    with pytest.raises(RuntimeError), Session.create(path, overwrite=True) as s:
        raise RuntimeError("failed before holding anything")
    with Session.open(path) as s:
        assert s.attrs["description"] == "keep me" and s.status == "closed"
    assert only_file(tmp_path) == ["s.h5"]
    with pytest.raises(RuntimeError), Session.create(path, overwrite=True, description="new") as s:
        s.write_group("calibration/cam", {"k": [1.0]})
        raise RuntimeError("failed after writing: that is kept, as an aborted session")
    with Session.open(path) as s:
        assert s.attrs["description"] == "new" and s.status == "aborted" and s.exists("calibration/cam")
    assert only_file(tmp_path) == ["s.h5"]


def test_calibrate_into_a_new_session_with_overwrite(tmp_path: Path) -> None:
    from tests.plugins.photogrammetry.scenes import F1, grid_points

    film, grid = grid_points()
    points = tmp_path / "grid.csv"
    points.write_text("x,y,plane_x,plane_y\n" + "\n".join(",".join(f"{v:.17g}" for v in (*a, *b))
                                                          for a, b in zip(film, grid)) + "\n")
    session = tmp_path / "cal.h5"
    args = ("calibrate", "--points", str(points), "--camera-center", ",".join(f"{v:.17g}" for v in F1),
            "--session", str(session), "--no-progress")
    assert run_cli(*args).returncode == 0
    first = session_id(session)
    again = run_cli(*args)  # an existing session is added to: the camera is already there
    assert again.returncode == 1 and "/calibration/cam already exists" in again.stderr
    replaced = run_cli(*args, "--overwrite")
    assert replaced.returncode == 0, replaced.stderr
    assert session_id(session) != first and only_file(tmp_path) == ["cal.h5", "grid.csv"]
