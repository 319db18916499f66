"""How long ``record`` records, said on the terminal: the default, 0 = until the sources end, early ends."""

from __future__ import annotations

from pathlib import Path

import pytest
from mirrorlab.core import Session, ValidationError

from tests.support import run_cli

#: Three rendered frames of the virtual RSSR scene at 100 Hz: a finite source that needs no port.
SETTINGS = {"source": "virtual", "scene": "rssr", "scene_frames": 3, "frame_rate": 100.0, "lines": 16}
VIRTUAL = ("--source", "virtual", "--scene", "rssr", "--scene-frames", "3", "--frame-rate", "100",
           "--lines", "16", "--no-progress")


def test_help_shows_the_default_duration_and_what_0_means() -> None:
    text = " ".join(run_cli("record", "film_scanner", "--help").stdout.split())
    assert "how long to record [s] (default 5; 0 = until every source has ended" in text


def test_seconds_0_records_until_the_source_ends_and_says_so(tmp_path: Path) -> None:
    out = tmp_path / "all.h5"
    proc = run_cli("record", "film_scanner", "--out", str(out), "--seconds", "0", *VIRTUAL)
    assert proc.returncode == 0, proc.stderr
    assert "until the source ended (--seconds 0)" in proc.stdout
    assert "dev/frames: 3 samples" in proc.stdout and proc.stderr == ""
    bad = run_cli("record", "film_scanner", "--out", str(tmp_path / "neg.h5"), "--seconds", "-1", *VIRTUAL)
    assert bad.returncode == 2 and "below the minimum 0.0 s" in bad.stderr


def test_a_source_that_ends_early_is_a_warning_on_the_terminal(tmp_path: Path) -> None:
    out = tmp_path / "short.h5"
    # the source ends after 3 frames; recording stops then, long before the requested 600 s
    proc = run_cli("record", "film_scanner", "--out", str(out), "--seconds", "600", *VIRTUAL)
    assert proc.returncode == 0, proc.stderr
    [line] = proc.stderr.splitlines()  # one line, not wrapped at 80 columns
    assert line.startswith("warning: dev: source ended after about ")
    assert line.endswith(" s, before the requested 600 s; the recording holds what it delivered")
    assert "of the requested 600 s (--seconds)" in proc.stdout and "dev/frames: 3 samples" in proc.stdout


def test_api_record_0_is_until_the_end_as_in_a_recipe(tmp_path: Path) -> None:
    with Session.create(tmp_path / "api.h5") as s:
        s.add_instrument("cam", "film_scanner", settings=SETTINGS)
        stats = s.record(0)
        assert stats["cam/frames"]["samples"] == 3 and s.recorded_seconds > 0
        with pytest.raises(ValidationError, match="must be >= 0"):
            s.record(-1)
        kinds = [e["kind"] for e in s.log()]
    assert "recording_stopped" in kinds and "source_ended" not in kinds  # 0 asks for all: no early end
