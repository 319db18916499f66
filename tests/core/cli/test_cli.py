"""The CLI through subprocesses: recipes (valid and malformed), session commands, analyze, exit codes."""

from __future__ import annotations

import json
from pathlib import Path

import h5py

from tests.support import run_cli

GOOD = """
[session]
description = "thermometer check"
operator = "ana"

[instruments.thermo]
plugin = "acme_thermometer"
simulate = true
[instruments.thermo.settings]
rate = "0.1 kHz"
[instruments.thermo.simulator]
seed = 7

[[steps]]
action = "acquire"
seconds = 5

[[steps]]
action = "run"
algorithm = "acme_drift_rate"
inputs = { time = "/instruments/thermo/temperature/time", values = "/instruments/thermo/temperature/data" }
parameters = { skip = "100 ms" }
"""

BAD = """
[session]
operater = "typo"

[instruments.thermo]
plugin = "acme_thermometer"
[instruments.thermo.settings]
rate = "5 mm"
colour = "red"

[instruments.cam]
plugin = "no_such_plugin"
simulate = true

[[steps]]
action = "acquire"
seconds = -1

[[steps]]
action = "dance"
"""


def test_version() -> None:
    proc = run_cli("--version")
    assert proc.returncode == 0 and proc.stdout.startswith("mirrorlab ")


def test_malformed_recipe_lists_every_problem_and_exits_2(tmp_path: Path, acme_site: Path) -> None:
    recipe = tmp_path / "bad.toml"
    recipe.write_text(BAD)
    proc = run_cli("run", str(recipe), "--out", str(tmp_path / "x.h5"), sites=(acme_site,))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    lines = proc.stderr.strip().splitlines()
    f = str(recipe)
    expected = [
        f"{f}: session.operater: unknown parameter",
        f"{f}: instruments.thermo.settings.colour: unknown parameter",
        f"{f}: instruments.thermo.settings.rate: wrong unit: cannot convert mm (length) to Hz (frequency)",
        f"{f}: instruments.thermo.port: required unless simulate = true",
        f"{f}: instruments.cam.plugin: no instrument named 'no_such_plugin'",
        f"{f}: steps.0.seconds: -1.0 s is below the minimum 0.0 s",
        f"{f}: steps.1.action: no step named 'dance'",
    ]
    for text in expected:
        assert any(text in line for line in lines), (text, lines)
    assert len(lines) == len(expected)
    assert not (tmp_path / "x.h5").exists()


def test_invalid_toml_and_missing_file(tmp_path: Path) -> None:
    broken = tmp_path / "broken.toml"
    broken.write_text("[session\n")
    proc = run_cli("run", str(broken))
    assert proc.returncode == 2 and f"{broken}: not a TOML recipe" in proc.stderr
    proc = run_cli("run", str(tmp_path / "missing.toml"))
    assert proc.returncode == 2 and "cannot read the recipe" in proc.stderr


def test_run_recipe_with_overrides_then_inspect(tmp_path: Path, acme_site: Path) -> None:
    recipe = tmp_path / "thermo.toml"
    recipe.write_text(GOOD)
    out = tmp_path / "thermo.h5"
    proc = run_cli("run", str(recipe), "--out", str(out), "--set", "steps.0.seconds=1.5",
                   "--set", "session.operator=bo", sites=(acme_site,))
    assert proc.returncode == 0, proc.stderr
    assert "thermo/temperature:" in proc.stdout and "/results/acme_drift_rate/run-0001: ok" in proc.stdout

    info = json.loads(run_cli("session", "info", str(out), "--json", sites=(acme_site,)).stdout)
    assert info["attributes"]["operator"] == "bo" and info["attributes"]["status"] == "closed"
    samples = info["instruments"]["thermo"]["streams"]["temperature"]["samples"]
    assert 100 <= samples <= 250  # 1.5 s at 100 Hz, not the recipe's 5 s
    with h5py.File(out, "r") as f:
        assert json.loads(f["config"].attrs["overrides"]) == ["steps.0.seconds=1.5", "session.operator=bo"]
        assert f["config/recipe"][()].decode() == GOOD
        assert f["config"].attrs["recipe_hash"].startswith("sha256:")

    tree = run_cli("session", "tree", str(out))
    assert tree.returncode == 0 and "temperature/" in tree.stdout and "data  [" in tree.stdout
    check = run_cli("session", "check", str(out), "--json")
    assert check.returncode == 0 and json.loads(check.stdout)["complete"] is True
    csv = run_cli("session", "export", str(out), "thermo/temperature")
    rows = csv.stdout.strip().splitlines()
    assert rows[0] == "time_s,temperature_K" and len(rows) == samples + 1

    analyze = run_cli("analyze", "acme_drift_rate", str(out), "--input", "time=/instruments/thermo/temperature/time",
                      "--input", "values=/instruments/thermo/temperature/data", "--skip", "0.5 s", sites=(acme_site,))
    assert analyze.returncode == 0, analyze.stderr
    assert "/results/acme_drift_rate/run-0002: ok" in analyze.stdout
    bad = run_cli("analyze", "acme_drift_rate", str(out), "--skip", "-3", sites=(acme_site,))
    assert bad.returncode == 2 and "skip: -3.0 s is below the minimum" in bad.stderr


def test_record_command_generated_from_settings(tmp_path: Path, acme_site: Path) -> None:
    out = tmp_path / "rec.h5"
    proc = run_cli("record", "acme_thermometer", "--simulate", "--seconds", "0.5", "--rate", "50",
                   "--out", str(out), sites=(acme_site,))
    assert proc.returncode == 0, proc.stderr
    with h5py.File(out, "r") as f:
        assert json.loads(f["instruments/dev"].attrs["settings"]) == {"rate": 50.0}
    help_text = run_cli("record", "acme_thermometer", "--help", sites=(acme_site,)).stdout
    assert "--rate FLOAT" in help_text and "[Hz]" in help_text


def test_session_new_and_errors(tmp_path: Path) -> None:
    path = tmp_path / "new.h5"
    assert run_cli("session", "new", str(path), "--operator", "ana").returncode == 0
    assert run_cli("session", "check", str(path)).returncode == 0
    again = run_cli("session", "new", str(path))
    assert again.returncode == 1 and "already exists" in again.stderr
    missing = run_cli("session", "info", str(tmp_path / "nope.h5"))
    assert missing.returncode == 2 and "no such file or folder" in missing.stderr
    assert run_cli("session").returncode == 2



def test_acquire_step_subset_must_name_recipe_instruments(tmp_path: Path, acme_site: Path) -> None:
    recipe = tmp_path / "subset.toml"
    recipe.write_text(GOOD.replace('action = "acquire"\nseconds = 5', 'action = "acquire"\nseconds = 1\n'
                                   'instruments = "thermo, cam"'))
    proc = run_cli("run", str(recipe), "--check", sites=(acme_site,))
    assert proc.returncode == 2
    assert "steps.0.instruments: no instrument 'cam' in the recipe; it has: thermo" in proc.stderr
    ok = run_cli("run", str(recipe), "--out", str(tmp_path / "s.h5"), "--set", 'steps.0.instruments="thermo"',
                 sites=(acme_site,))
    assert ok.returncode == 0, ok.stderr
