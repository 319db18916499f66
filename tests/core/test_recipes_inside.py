"""Recipes stay inside (issue 20): ports, the files and folders a recipe writes, labels that name HDF5
groups, free text, nesting. Every check is made when the recipe is validated, so ``run --check``
reports it (exit 2, file, key and reason) and nothing is opened, created or replaced."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from mirrorlab.core.errors import ValidationError
from mirrorlab.core.session import Session

from tests.support import run_cli

#: A recorded instrument on a real port (not simulated): what a recipe from another lab could hold.
SCANNER = ('[instruments.scanner]\nplugin = "film_scanner"\nport = "{port}"\n'
           '[instruments.scanner.settings]\nsource = "fscan"\n\n[[steps]]\naction = "acquire"\nseconds = 1\n')
#: An analysis step that writes PNG figures into ``figures``.
REPORT = '[[steps]]\naction = "report"\ninstrument = "cam"\nfigures = "{figures}"\n'


def _recipe(folder: Path, text: str, name: str = "r.toml") -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(text)
    return path


@pytest.mark.parametrize("url", ["spy://loop://?file={victim}", "SPY://loop://?file={victim}", "alt://{victim}",
                                 "hwgrep://.*"])
def test_a_port_url_that_reaches_files_or_other_devices_is_refused(url: str, tmp_path: Path) -> None:
    """``spy://loop://?file=VICTIM`` passed --check and truncated VICTIM when run."""
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    port = url.format(victim=victim)
    recipe = _recipe(tmp_path / "lab", SCANNER.format(port=port))
    out = tmp_path / "s.h5"
    for extra in (["--check"], []):
        proc = run_cli("run", str(recipe), "--out", str(out), "--no-progress", *extra)
        assert proc.returncode == 2, proc.stderr
        assert (f"mirrorlab: error: {recipe}: instruments.scanner.port: {port!r} is a pyserial URL of kind "
                f"{port.partition('://')[0]}://: a port is a device path") in proc.stderr
        assert "add --allow-port-url" in proc.stderr
    assert victim.read_text() == "precious\n" and not out.exists()
    allowed = run_cli("run", str(recipe), "--check", "--allow-port-url")
    assert allowed.returncode == 0, allowed.stderr


@pytest.mark.parametrize("port", ["/dev/ttyUSB0", "socket://127.0.0.1:5000", "loop://", "rfc2217://10.0.0.2:2217"])
def test_device_paths_and_plain_urls_need_no_option(port: str, tmp_path: Path) -> None:
    proc = run_cli("run", str(_recipe(tmp_path, SCANNER.format(port=port))), "--check")
    assert proc.returncode == 0, proc.stderr


def test_record_demo_and_tui_refuse_a_port_url_too(tmp_path: Path) -> None:
    victim = tmp_path / "victim.txt"
    victim.write_text("precious\n")
    port = f"spy://loop://?file={victim}"
    record = run_cli("record", "film_scanner", "--out", str(tmp_path / "r.h5"), "--port", port, "--no-progress")
    assert record.returncode == 2 and "--port: " in record.stderr and "--allow-port-url" in record.stderr
    demo = run_cli("demo", "--out", str(tmp_path / "d.h5"), "--set", f'instruments.rssr.port="{port}"',
                   "--no-progress")
    assert demo.returncode == 2 and "instruments.rssr.port" in demo.stderr, demo.stderr
    tui = run_cli("tui", str(_recipe(tmp_path / "lab", SCANNER.format(port=port))), "--out", str(tmp_path / "t.h5"))
    assert tui.returncode == 2 and "instruments.scanner.port" in tui.stderr, tui.stderr
    assert victim.read_text() == "precious\n"
    assert not any(p.suffix == ".h5" for p in tmp_path.iterdir())


def test_outputs_outside_the_recipe_and_session_folders_are_refused(tmp_path: Path) -> None:
    """``figures = "/anywhere"`` created folders anywhere; ``..`` and a link out of the folder too."""
    lab, outside = tmp_path / "lab", tmp_path / "outside"
    outside.mkdir()
    lab.mkdir()
    (lab / "link").symlink_to(outside, target_is_directory=True)
    for given, shown in ((str(outside / "figs"), repr(str(outside / "figs"))),
                         ("../outside/figs", repr(str(outside / "figs"))),
                         ("link/figs", f"{str(lab / 'link' / 'figs')!r} (through a link: {str(outside / 'figs')!r})"),
                         ("/", "'/'")):
        recipe = _recipe(lab, REPORT.format(figures=given))
        proc = run_cli("run", str(recipe), "--check")
        assert proc.returncode == 2, (given, proc.stderr)
        assert (f"mirrorlab: error: {recipe}: steps.0.figures: {shown} is outside the recipe's folder ({lab}) "
                f"and the session file's ({lab / 'out'}); name a folder inside one of them") in proc.stderr
    assert list(outside.iterdir()) == []


def test_outputs_inside_the_recipe_or_session_folder_are_accepted(tmp_path: Path) -> None:
    lab, runs = tmp_path / "lab", tmp_path / "runs"
    runs.mkdir()
    assert run_cli("run", str(_recipe(lab, REPORT.format(figures="figs/a"))), "--check").returncode == 0
    # beside the session named by --out, wherever that is
    recipe = _recipe(lab, REPORT.format(figures=runs / "figs"))
    assert run_cli("run", str(recipe), "--check").returncode == 2
    proc = run_cli("run", str(recipe), "--check", "--out", str(runs / "s.h5"))
    assert proc.returncode == 0, proc.stderr


def test_an_output_folder_holding_files_needs_overwrite(tmp_path: Path) -> None:
    lab = tmp_path / "lab"
    (lab / "figs").mkdir(parents=True)
    (lab / "figs" / "walls.png").write_bytes(b"earlier figure")
    recipe = _recipe(lab, REPORT.format(figures="figs"))
    proc = run_cli("run", str(recipe), "--check")
    assert proc.returncode == 2
    assert (f"{recipe}: steps.0.figures: {str(lab / 'figs')!r} already holds files; add --overwrite to replace them, or name "
            "another folder") in proc.stderr
    assert run_cli("run", str(recipe), "--check", "--overwrite").returncode == 0
    (lab / "plain").write_text("a file")
    proc = run_cli("run", str(_recipe(lab, REPORT.format(figures="plain"))), "--check", "--overwrite")
    assert proc.returncode == 2 and f"steps.0.figures: {str(lab / 'plain')!r} is a file; name a folder" in proc.stderr


@pytest.mark.data
def test_the_retarget_csv_never_replaces_a_file_without_overwrite(tmp_path: Path, shared_data: Path) -> None:
    """``csv = "/abs/existing"`` was overwritten without asking."""
    lab = tmp_path / "lab"
    recipe = _recipe(lab, f'[[steps]]\naction = "retarget"\nfile = "{shared_data / "bvh" / "01_01.bvh"}"\n'
                          'joints = "RightArm,RightForeArm,RightHand,RFingers"\nscale = 56.444\nskip = 2000\n'
                          'lengths = "295.87,229.54"\naxes = "zyx,y"\ncsv = "arm.csv"\n')
    (lab / "arm.csv").write_text("mine\n")
    proc = run_cli("run", str(recipe), "--out", str(lab / "s.h5"), "--no-progress")
    assert proc.returncode == 2
    assert (f"{recipe}: steps.0.csv: {str(lab / 'arm.csv')!r} already exists; add --overwrite to replace it, or name another "
            "file") in proc.stderr
    assert (lab / "arm.csv").read_text() == "mine\n" and not (lab / "s.h5").exists()
    proc = run_cli("run", str(recipe), "--out", str(lab / "s.h5"), "--no-progress", "--overwrite")
    assert proc.returncode == 0, proc.stderr
    assert (lab / "arm.csv").read_text().startswith("frame,time_s,")
    # an analysis on an existing session: --overwrite replaces what the recipe writes
    analysis = _recipe(lab, recipe.read_text().replace("skip = 2000", 'skip = 2000\nname = "again"'), "a.toml")
    assert run_cli("run", str(analysis), "--session", str(lab / "s.h5"), "--no-progress").returncode == 2
    proc = run_cli("run", str(analysis), "--session", str(lab / "s.h5"), "--no-progress", "--overwrite")
    assert proc.returncode == 0, proc.stderr


@pytest.mark.parametrize("label", ["/truth/fake", "/results/derivatives/run-0001", "", ".", "..", "a\\u0000b",
                                   "1st", "cam 1", "a.b"])
def test_instrument_and_controller_labels_are_identifiers(label: str, tmp_path: Path) -> None:
    """``[instruments."/truth/fake"]`` wrote under /truth and "/results/..." planted a fake result."""
    recipe = _recipe(tmp_path, f'[instruments."{label}"]\nplugin = "film_scanner"\nsimulate = true\n'
                               f'[controllers."{label}"]\nplugin = "follow"\n'
                               '[[steps]]\naction = "acquire"\nseconds = 1\n')
    proc = run_cli("run", str(recipe), "--check")
    assert proc.returncode == 2
    # a NUL (or any control character) reaches the terminal escaped, in the key and in the reason
    key, shown = label.replace("\\u0000", "\\x00"), repr(label.replace("\\u0000", "\0"))
    for kind in ("instrument", "controller"):
        assert (f"{recipe}: {kind}s.{key}: {shown} is not a label: use a letter or '_', then letters, digits, '_' "
                f"or '-' (e.g. 'cam_1'); it names the {kind}'s group in the session file") in proc.stderr
    assert "\0" not in proc.stderr


def test_the_session_api_refuses_a_label_that_is_no_identifier(tmp_path: Path) -> None:
    with Session.create(tmp_path / "s.h5") as session:
        with pytest.raises(ValidationError, match="'/truth/fake' is not a label"):
            session.add_instrument("/truth/fake", "film_scanner", simulate=True)
        with pytest.raises(ValidationError, match="'..' is not a label"):
            session.add_controller("..", "follow", inputs={}, instruments={})


@pytest.mark.parametrize("key", ["operator", "description"])
def test_session_text_holds_no_control_characters(key: str, tmp_path: Path) -> None:
    recipe = _recipe(tmp_path, f'[session]\n{key} = "ana\\u001b]0;owned\\u0007"\n'
                               '[[steps]]\naction = "wait"\nseconds = 0\n')
    proc = run_cli("run", str(recipe), "--check")
    assert proc.returncode == 2
    assert (f"{recipe}: session.{key}: holds the control character '\\x1b' at character 4; write plain "
            "text") in proc.stderr
    new = run_cli("session", "new", str(tmp_path / "s.h5"), f"--{key}", "line\nbreak")
    assert new.returncode == 2 and f"--{key}: holds the control character '\\n' at character 5" in new.stderr
    assert not (tmp_path / "s.h5").exists()


def test_a_recipe_nested_500_deep_is_a_validation_error(tmp_path: Path) -> None:
    """It exited 1 with RecursionError."""
    for text in ("x = " + "[" * 500 + "]" * 500, "x = " + "{a = " * 500 + "1" + "}" * 500,
                 "x = " + "[" * 40 + "]" * 40):
        recipe = _recipe(tmp_path, text + "\n")
        proc = run_cli("run", str(recipe), "--check")
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr == (f"mirrorlab: error: {recipe}: tables or arrays nest deeper than 32 levels; a recipe "
                               "needs a few (see docs/ARCHITECTURE.md, Recipes)\n")
    proc = run_cli("run", str(_recipe(tmp_path, REPORT.format(figures="f"))), "--check",
                   "--set", "steps.0.figures=" + "[" * 500 + "]" * 500)
    assert proc.returncode == 2 and "--set steps.0.figures: the value nests deeper than 32 levels" in proc.stderr


def test_checks_apply_to_every_recipe_command_with_its_folder(tmp_path: Path) -> None:
    """``mirrorlab batch`` checks the recipe's outputs against its --out folder before copying anything."""
    lab = tmp_path / "lab"
    recipe = _recipe(lab, REPORT.format(figures=tmp_path / "elsewhere"))
    source = tmp_path / "in.h5"
    with Session.create(source):
        pass
    proc = run_cli("batch", str(recipe), str(source), "--out", str(tmp_path / "batch"), "--workers", "1",
                   "--no-progress")
    assert proc.returncode == 2 and "steps.0.figures" in proc.stderr and "is outside" in proc.stderr, proc.stderr
    assert not (tmp_path / "elsewhere").exists() and os.listdir(tmp_path / "batch") == []
