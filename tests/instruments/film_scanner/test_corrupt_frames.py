"""A damaged image in a folder source is a data error, reported once; the source stops, never loops.

Before, a corrupt frame raised ``DeviceDisconnected``: the instrument reconnected, the folder
restarted from its first frame, and the recording held frames ``0, 1, 0, 1, …`` until stopped.
"""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from mirrorlab.core import Session
from mirrorlab.core.errors import DataError
from mirrorlab.instruments.film_scanner.sources import FolderSource

from tests.support import run_cli


def folder(tmp_path: Path, suffix: str, damage: str) -> Path:
    """Four frames ``0..3``; frame 2 cut in half (``cut``) or not an image at all (``text``)."""
    out = tmp_path / "frames"
    out.mkdir()
    for k in range(4):
        img = np.full((96, 128), 40 * k, np.uint8)
        cv2.circle(img, (20 + 25 * k, 48), 12, 255, -1)
        cv2.imwrite(str(out / f"{k}{suffix}"), img)
    bad = out / f"2{suffix}"
    data = bad.read_bytes()
    bad.write_bytes(data[: len(data) // 2] if damage == "cut" else b"not an image\n")
    return out


@pytest.mark.parametrize(("suffix", "damage"), [(".png", "cut"), (".jpg", "cut"), (".png", "text")])
def test_a_damaged_frame_stops_the_source_with_one_data_error(tmp_path: Path, suffix: str, damage: str) -> None:
    frames = folder(tmp_path, suffix, damage)
    source = FolderSource(frames)
    source.open()
    assert [source.read()[0] for _ in range(2)] == [0, 1]
    with pytest.raises(DataError, match=rf"2{suffix}.*(cut short|cannot be decoded).*replace or remove it"):
        source.read()
    with Session.create(tmp_path / "s.h5") as s:
        s.add_instrument("cam", "film_scanner", settings={"source": "folder", "path": str(frames),
                                                          "frame_rate": 1000.0, "lines": 16})
        s.record(0)  # until the source ends or fails: it must fail, not loop
        index = s.stream("cam", "frame_index").data.tolist()
        kinds = [e["kind"] for e in s.log() if e["source"] == "cam"]
        assert isinstance(s.instruments["cam"].failed, DataError)
    assert index == [0, 1]
    assert kinds.count("failed") == 1 and "connection_lost" not in kinds and "reconnected" not in kinds


def test_cli_record_of_a_damaged_folder_says_so_once_and_exits_1(tmp_path: Path) -> None:
    frames = folder(tmp_path, ".png", "cut")
    proc = run_cli("record", "film_scanner", "--source", "folder", "--path", str(frames), "--frame-rate", "1000",
                   "--lines", "16", "--seconds", "0", "--no-progress", "--out", str(tmp_path / "s.h5"))
    assert proc.returncode == 1
    errors = [line for line in proc.stderr.splitlines() if line.startswith("error: dev: ")]
    assert len(errors) == 1 and "2.png' cannot be decoded" in errors[0] and "replace or remove it" in errors[0]
    assert "reconnect" not in proc.stderr
    assert "dev/frames: 2 samples" in proc.stdout
