"""Damage that used to pass: ``session check`` reads every object (a damaged object header of ``/log``,
``/config/...`` or an instrument's group), ``check --data`` verifies the recorded streams' Fletcher-32
checksums chunk by chunk, and an instrument that failed while recording makes ``check`` and the
recording command's exit code say so (issue 20, item 5)."""

from __future__ import annotations

import shutil
import threading
from pathlib import Path

import h5py
import numpy as np
import pytest
from mirrorlab.core import DamagedFileError, Session
from mirrorlab.core.cli.run_cmd import print_summary
from mirrorlab.core.events import Event

from tests.support import run_cli

HANG = 60.0  # s: only turns a hang into a failure
#: the angle source's stream at 100 Hz is chunked by 100 samples: 3.5 s give four chunks
RATE, SECONDS, CHUNK = 100.0, 3.5, 100


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("integrity") / "angle.h5"
    with Session.create(path, description="four chunks of a reference angle") as s:
        s.add_instrument("angle", "angle_source", simulate=True, settings={"rate": RATE})
        s.record(SECONDS)
    with h5py.File(path, "r") as f:
        ds = f["instruments/angle/angle/data"]
        assert ds.fletcher32 and ds.chunks == (CHUNK,) and ds.shape[0] > 3 * CHUNK, (ds.chunks, ds.shape)
    return path


def damaged_copy(source: Path, where: Path, offset: int) -> Path:
    """A copy of ``source`` with every bit of the byte at ``offset`` inverted."""
    path = where / f"damaged-{offset}.h5"
    shutil.copy(source, path)
    with path.open("r+b") as f:
        f.seek(offset)
        byte = f.read(1)[0]
        f.seek(offset)
        f.write(bytes([byte ^ 0xFF]))
    return path


def header_address(path: Path, name: str) -> int:
    with h5py.File(path, "r") as f:
        return int(h5py.h5o.get_info(f[name].id).addr)


def test_an_intact_recording_checks_complete_with_its_checksums(recorded: Path) -> None:
    proc = run_cli("session", "check", str(recorded), "--data")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "complete" in proc.stdout and "without checksums" not in proc.stdout


@pytest.mark.parametrize("name", ["log", "config/recipe", "config/provenance", "truth", "controllers"])
def test_a_damaged_object_header_is_found(name: str, recorded: Path, tmp_path: Path) -> None:
    """The object's header checksum no longer matches (a byte inside it changed): opening the file and
    its root still work, so only reading the object itself shows the damage."""
    path = damaged_copy(recorded, tmp_path, header_address(recorded, name) + 6)
    proc = run_cli("session", "check", str(path))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert f"damaged: /{name}" in proc.stdout and "restore the file from a backup" in proc.stdout, proc.stdout


def test_check_data_finds_a_changed_sample_in_a_middle_chunk(recorded: Path, tmp_path: Path) -> None:
    """One bit changed in the second chunk of the recorded angles: the first and last chunks read (plain
    ``check`` passes); ``check --data`` reads every chunk and names the samples whose checksum fails."""
    with h5py.File(recorded, "r") as f:
        offset = f["instruments/angle/angle/data"].id.get_chunk_info_by_coord((CHUNK,)).byte_offset
    path = damaged_copy(recorded, tmp_path, offset + 17)
    assert run_cli("session", "check", str(path)).returncode == 0
    proc = run_cli("session", "check", str(path), "--data")
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert f"/instruments/angle/angle/data: samples {CHUNK}-{2 * CHUNK} do not match their checksum" in proc.stdout
    # the changed value is never exported as if it were the recorded one
    export = run_cli("session", "export", str(path), "angle/angle")
    assert export.returncode == 1 and export.stdout == "", export.stdout[-200:]


def test_a_file_without_checksums_says_it_cannot_verify(recorded: Path, tmp_path: Path) -> None:
    """A file written before checksums (datasets without the filter) reads, and says so."""
    path = tmp_path / "plain.h5"
    with h5py.File(recorded, "r") as src, h5py.File(path, "w", libver="latest") as dst:
        for key, value in src.attrs.items():
            dst.attrs[key] = value
        for name in src:
            src.copy(src[name], dst, name=name)
        for part in ("data", "time"):  # rewritten without the filter, as older mirrorlab wrote them
            values = dst[f"instruments/angle/angle/{part}"][()]
            del dst[f"instruments/angle/angle/{part}"]
            dst.create_dataset(f"instruments/angle/angle/{part}", data=values, maxshape=(None,), chunks=(CHUNK,))
    proc = run_cli("session", "check", str(path), "--data")
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "written without checksums" in proc.stdout


def test_an_instrument_that_failed_while_recording_is_reported(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    """No reconnect budget: the device's connection drops during the recording and the instrument fails;
    the recording goes on and closes, but ``check`` and the recording's summary (its exit code) say so."""
    path = tmp_path / "failed.h5"
    failed = threading.Event()

    def on_event(e: Event) -> None:
        if e.source == "angle" and e.kind == "failed":
            failed.set()

    with Session.create(path) as s:
        s.events.subscribe(on_event)
        s.add_instrument("angle", "angle_source", simulate=True, reconnect=0)
        samples = s.subscribe("angle", "angle")
        s.start_acquisition()
        s.start_recording()
        samples.drain()  # what arrives from now on is also recorded
        assert samples.get(timeout=HANG) is not None
        s.simulator("angle").disconnect()
        assert failed.wait(HANG), "the instrument did not fail"
        s.stop_recording()
        s.stop_acquisition()
        recorded = s.stream("angle", "angle").times
    assert len(recorded) > 0 and np.all(np.isfinite(recorded))
    proc = run_cli("session", "check", str(path))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "instrument angle failed at" in proc.stdout, proc.stdout
    capsys.readouterr()
    assert print_summary(path, allow_empty=False) == 1
    assert "mirrorlab: error: instrument angle failed at" in capsys.readouterr().err
    assert print_summary(path) == 0  # after an analysis of it: the recording's failure is not the analysis's


@pytest.mark.parametrize("read", ["describe", "log", "tree"])
def test_the_read_api_reports_a_damaged_object_in_plain_words(read: str, recorded: Path, tmp_path: Path) -> None:
    """What the console and the CLI show for a damaged ``/log``: the one line naming the file, never h5py's
    text (the console puts ``str(error)`` of a MirrorlabError in its dialog)."""
    path = damaged_copy(recorded, tmp_path, header_address(recorded, "log") + 6)
    with Session.open(path) as s, pytest.raises(DamagedFileError) as caught:
        getattr(s, read)()
    assert str(caught.value).startswith(f"{path}: truncated or damaged HDF5 file"), caught.value
    assert "synchronously" not in str(caught.value)
