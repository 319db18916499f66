"""Help and output texts of every command: plain text, every option explained, bounds and choices readable."""

from __future__ import annotations

import argparse
import json
import re
from collections.abc import Iterator

import pytest

from tests.support import run_cli


def _parsers() -> Iterator[tuple[str, argparse.ArgumentParser]]:
    from mirrorlab.core.cli import build_parser

    todo = [("mirrorlab", build_parser())]
    while todo:
        name, parser = todo.pop()
        yield name, parser
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                todo += [(f"{name} {sub}", p) for sub, p in action.choices.items()]


PARSERS = dict(_parsers())


@pytest.mark.parametrize("name", sorted(PARSERS))
def test_help_is_plain_and_every_option_explained(name: str) -> None:
    parser = PARSERS[name]
    text = parser.format_help()
    assert "`" not in text, f"reStructuredText in `{name} --help`"
    assert "None" not in text, f"a bound or default printed as None in `{name} --help`"
    assert ", ," not in text and "one of ," not in text and "default )" not in text, name
    undocumented = [a.option_strings or [a.dest] for a in parser._actions
                    if not a.help and not isinstance(a, argparse._SubParsersAction)]
    assert not undocumented, f"`{name}` options without help: {undocumented}"


def test_bounds_and_empty_choices_are_readable() -> None:
    text = PARSERS["mirrorlab analyze filter"].format_help()
    assert re.search(r"--lam FLOAT\s+.*\(≥ -1\.0; default -1\.0\)", " ".join(text.split()))
    scanner = " ".join(PARSERS["mirrorlab record film_scanner"].format_help().split())
    assert 'one of "", rssr, four_bar' in scanner and 'default "")' in scanner


def test_plugins_show_json_after_the_subcommand_or_before() -> None:
    for args in (("plugins", "--json", "show", "filter"), ("plugins", "show", "filter", "--json")):
        proc = run_cli(*args)
        assert proc.returncode == 0 and json.loads(proc.stdout)["name"] == "filter", proc.stdout


def test_plugins_show_step_lists_its_tables_and_keeps_help_apart() -> None:
    proc = run_cli("plugins", "show", "run")
    assert proc.returncode == 0
    assert re.search(r"^  tables:\n    inputs +input name = dataset path", proc.stdout, re.M), proc.stdout
    assert re.search(r"^    parameters +the algorithm's parameters", proc.stdout, re.M), proc.stdout
    shown = run_cli("plugins", "show", "filter").stdout
    # choices and the help each on a line of their own
    assert re.search(r"^    method +str +one of thesis, butterworth, smoothing_spline; default thesis$", shown, re.M)
    assert re.search(r"^    lam +float +≥ -1\.0; default -1\.0$", shown, re.M), shown


def test_check_pluralises(tmp_path) -> None:
    recipe = tmp_path / "one.toml"
    recipe.write_text('[instruments.cam]\nplugin = "film_scanner"\nsimulate = true\n\n[[steps]]\naction = "acquire"\n'
                      "seconds = 1\n")
    proc = run_cli("run", str(recipe), "--check")
    assert proc.returncode == 0 and proc.stdout.strip().endswith("ok (1 instrument, 1 step)"), proc.stdout


def test_set_unknown_instrument_names_the_option(tmp_path) -> None:
    from tests.support import REPO

    proc = run_cli("run", str(REPO / "sessions" / "scan_film.toml"), "--check", "--set", "instruments.nope.settings.lines=3")
    assert proc.returncode == 2
    assert proc.stderr.strip() == ("mirrorlab: error: --set instruments.nope.settings.lines: no instrument 'nope' in "
                                   "the recipe; it has: scanner")


def test_toml_error_names_the_file_without_placeholder_key(tmp_path) -> None:
    broken = tmp_path / "broken.toml"
    broken.write_text("[session\n")
    proc = run_cli("run", str(broken))
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"mirrorlab: error: {broken}: not a TOML recipe: ") and " -: " not in proc.stderr


def test_run_help_names_the_real_default_output_folder(tmp_path) -> None:
    from tests.support import REPO

    assert "out/<recipe>-<UTC time>.h5 in the recipe's folder" in " ".join(run_cli("run", "--help").stdout.split())
    recipe = tmp_path / "recipes" / "scan.toml"
    recipe.parent.mkdir()
    recipe.write_text((REPO / "sessions" / "scan_film.toml").read_text())
    proc = run_cli("run", str(recipe), "--set", "instruments.scanner.settings.scene_frames=2",
                   "--set", "instruments.scanner.settings.lines=16",
                   "--no-progress", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert len(list((recipe.parent / "out").glob("scan-*.h5"))) == 1 and not (tmp_path / "sessions").exists()


def test_calibrate_error_speaks_cli_and_pluralises(tmp_path) -> None:
    import cv2
    import numpy as np

    (tmp_path / "blank").mkdir()
    cv2.imwrite(str(tmp_path / "blank" / "white.png"), np.full((120, 160), 255, np.uint8))
    proc = run_cli("calibrate", "--images", str(tmp_path / "blank"), "--pattern", "10x7", "--square", "25", "--json",
                   "--no-progress")
    assert proc.returncode == 1
    (line,) = proc.stderr.splitlines()
    assert "no 10x7 chessboard found in 1 image;" in line and "pattern_size" not in line, line
    bad = run_cli("calibrate", "--images", str(tmp_path / "blank"), "--pattern", "10by7", "--square", "25", "--json")
    assert bad.returncode == 2 and bad.stderr.startswith("mirrorlab: error: --pattern: "), bad.stderr


def test_instrument_ready_message_names_no_none(tmp_path) -> None:
    from mirrorlab.core import Session

    messages: list[str] = []
    with Session.create(tmp_path / "s.h5") as s:
        s.events.subscribe(lambda e: messages.append(e.message))
        s.add_instrument("cam", "film_scanner", settings={"source": "virtual", "scene": "box", "lines": 16})
        s.add_instrument("sim", "film_scanner", simulate=True, settings={"lines": 16}, simulator={"clock": "FAST"})
    ready = [m for m in messages if " ready" in m]
    assert ready[0] == "film_scanner 'cam' ready" and ready[1] == "film_scanner 'sim' ready (simulated)", ready
