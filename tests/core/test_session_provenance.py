"""Provenance of result runs (status last, units, input digests, labels), the stored clock origin,
cancellation of algorithm runs, and schema 1 files, through real session files and the CLI."""

from __future__ import annotations

import hashlib
import json
import re
import subprocess
import sys
import threading
from collections.abc import Mapping
from datetime import timedelta
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from mirrorlab.core import Algorithm, Port, RunContext, Session, ValidationError
from mirrorlab.core.algorithms import execute
from mirrorlab.core.clock import ISO_FORMAT, parse_utc
from mirrorlab.core.store import schema

from tests.support import run_cli
from tests.tolerances import cond, roundoff

T = np.linspace(0.0, 10.0, 101)
KELVIN = 293.0 + 0.005 * T  # drifts 5 mK/s
#: Rounding bound of the drift rate fitted to T, KELVIN (K/s).
RATE_TOL = roundoff(cond=cond(np.column_stack([T, np.ones_like(T)])), scale=KELVIN.max() / np.ptp(T), ops=T.size)

INPUTS = {"time": "/truth/thermo/time", "values": "/truth/thermo/data"}


@pytest.fixture
def registry(acme_site: Path, with_sites):
    return with_sites(acme_site)


@pytest.fixture
def session_file(tmp_path: Path, registry) -> Path:
    """A closed session holding a stream-like group ``/truth/thermo/{time,data}`` (unit K, time in s)."""
    path = tmp_path / "prov.h5"
    with Session.create(path, registry=registry) as s:
        s.write_group("truth/thermo", {"time": T, "data": KELVIN}, {"unit": "K", "time_unit": "s"})
    return path


def sha256(a: np.ndarray) -> str:
    """The documented input digest of a 1-D float64 array: SHA-256 of the SHA-256 of each block of
    8192 values (64 KiB) in C order."""
    data = np.ascontiguousarray(a).tobytes()
    blocks = [data[i:i + 65536] for i in range(0, len(data), 65536)]
    return hashlib.sha256(b"".join(hashlib.sha256(b).digest() for b in blocks)).hexdigest()


def entry(a: np.ndarray) -> dict[str, Any]:
    return {"sha256": sha256(a), "block_rows": 8192, "dtype": "<f8", "shape": list(a.shape)}


def test_outputs_carry_declared_unit_and_description(session_file: Path, registry) -> None:
    with Session.open(session_file, writable=True, registry=registry) as s:
        ref = s.run("acme_drift_rate", INPUTS)
    with h5py.File(session_file, "r") as f:
        run = f[ref.path]
        assert run.attrs["status"] == "ok" and run.attrs["label"] == ""
        # a least-squares line through exact samples: rounding of values of 293 K, amplified by the
        # fit's conditioning, relative to the 10 s span
        assert float(run["rate"][()]) == pytest.approx(0.005, abs=RATE_TOL)
        # "{values}/s" is filled in with the unit of the dataset given as `values`
        assert (run["rate"].attrs["unit"], run["rate"].attrs["description"]) == ("K/s", "() drift per second")
        assert run["offset"].attrs["unit"] == "K" and run["residual_rms"].attrs["unit"] == "K"
        digests = json.loads(run.attrs["input_sha256"])
    assert digests["values"] == entry(KELVIN)
    assert digests["time"]["sha256"] == sha256(T)


def test_array_inputs_are_stored_by_their_sha256(session_file: Path, registry) -> None:
    values = np.stack([KELVIN, KELVIN], axis=1)[:, 0]  # a strided view: hashed as its values in C order
    with Session.open(session_file, writable=True, registry=registry) as s:
        ref = s.run("acme_drift_rate", {"time": T, "values": values})
        r = s.result(ref)
        unit = s.attributes(f"{ref.path}/rate")["unit"]
    assert r.attrs["inputs"] == {"time": "sha256:" + sha256(T), "values": "sha256:" + sha256(KELVIN)}
    assert r.attrs["input_sha256"]["values"] == entry(KELVIN)
    assert r.outputs["rate"] == pytest.approx(0.005, abs=RATE_TOL)              # as above
    assert unit == "{values}/s"  # an array has no unit: the declared placeholder says whose unit it is


def test_an_executor_stores_the_same_digests(session_file: Path, registry) -> None:
    """An executor hashes the inputs itself: the digests are those of a run without one."""
    from mirrorlab.core.batch.executors import Executor

    with Session.open(session_file, writable=True, registry=registry) as s:
        s.executor = Executor({"engine": "test"})
        r = s.result(s.run("acme_drift_rate", INPUTS))
    assert r.attrs["input_sha256"]["values"] == entry(KELVIN)
    assert r.attrs["input_sha256"]["time"]["sha256"] == sha256(T)


class Big(Algorithm):
    """Two outputs; the second too large for the file-size limit of the child below."""

    name = "big"
    version = "1.0.0"
    description = "a small and a large output"
    outputs = (Port("small", "(10,) first output", "mm"), Port("large", "(4e6,) second output", "mm"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict:
        return {"small": np.arange(10.0), "large": np.ones(4_000_000)}


INTERRUPTED = """
import os, resource, signal, sys
from mirrorlab.core import Session
from tests.core.test_session_provenance import Big
s = Session.open(sys.argv[1], writable=True)
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)           # a write past the limit fails with EFBIG
resource.setrlimit(resource.RLIMIT_FSIZE, (os.path.getsize(sys.argv[1]) + 2_000_000, resource.RLIM_INFINITY))
try:
    s.run(Big, {})
except Exception as exc:                                 # like a full disk
    print(type(exc).__name__, exc)
resource.setrlimit(resource.RLIMIT_FSIZE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))  # space again
s.close()
"""


def test_a_run_whose_writing_fails_is_incomplete_never_ok(session_file: Path, registry) -> None:
    child = subprocess.run([sys.executable, "-c", INTERRUPTED, str(session_file)], capture_output=True, text=True,
                           timeout=120, cwd=Path(__file__).parents[2])
    assert child.returncode == 0, child.stderr
    assert child.stdout.startswith("SessionError") and "File too large" in child.stdout
    with Session.open(session_file, registry=registry) as s:
        (ref,) = s.results("big")
        assert ref.status == "incomplete" and s.result(ref).attrs["status"] == "incomplete"
        assert "status" not in s.attributes(ref.path) and "small" in s.members(ref.path)  # written before the failure
        with pytest.raises(ValidationError, match="no successful run of 'big'"):
            s.resolve("@big/small")
        assert "result_incomplete" in [e["kind"] for e in s.log()]
    check = run_cli("session", "check", str(session_file))
    assert check.returncode == 1 and f"{ref.path} has no status" in check.stdout
    info = run_cli("session", "info", str(session_file))
    assert info.returncode == 0 and f"result {ref.path}: incomplete" in info.stdout


def test_labels_name_runs_apart(session_file: Path, registry) -> None:
    with Session.open(session_file, writable=True, registry=registry) as s:
        early = s.run("acme_drift_rate", INPUTS, label="all")
        late = s.run("acme_drift_rate", INPUTS, {"skip": "5 s"}, label="late")
        plain = s.run("acme_drift_rate", INPUTS, {"skip": "2 s"})
        assert s.resolve("@all/rate") == f"{early.path}/rate" and s.resolve("@late/offset") == f"{late.path}/offset"
        assert s.resolve("@acme_drift_rate/rate") == f"{plain.path}/rate"  # still the latest successful run
        for label, match in (("all", "already names /results/acme_drift_rate/run-0001"),
                             ("acme_drift_rate", "ambiguous"), ("derivatives", "ambiguous"),
                             ("two words", "not a run label"), ("9lives", "not a run label")):
            with pytest.raises(ValidationError, match=match):
                s.run("acme_drift_rate", INPUTS, label=label)
        with pytest.raises(ValidationError, match="run-0002 has no output 'slope'; it has: offset, rate"):
            s.resolve("@late/slope")
        failed = s.run("acme_drift_rate", INPUTS, {"skip": "100 s"}, label="retry")
        retried = s.run("acme_drift_rate", INPUTS, label="retry")  # a label is taken by a successful run only
        assert (failed.status, retried.status) == ("failed", "ok")
        assert s.resolve("@retry/rate") == f"{retried.path}/rate"
        chained = s.run("acme_drift_rate", {"time": "/truth/thermo/time", "values": "@late/rate"})
    assert chained.status == "failed"  # one value is too few to fit, but the reference resolved
    with Session.open(session_file, registry=registry) as s:
        assert [r.label for r in s.results()] == ["all", "late", "", "retry", "retry", ""]
        assert s.result(late).ref.label == "late" and s.result(chained).attrs["inputs"]["values"] == f"{late.path}/rate"
    info = run_cli("session", "info", str(session_file))
    assert f"result {late.path} as 'late': ok" in info.stdout and "rate: scalar float64 [K/s]" in info.stdout


LABEL_RECIPE = """
[instruments.thermo]
plugin = "acme_thermometer"
simulate = true
[instruments.thermo.settings]
rate = 100
[instruments.thermo.simulator]
clock = "FAST"

[[steps]]
action = "acquire"
seconds = 0.5

[[steps]]
action = "run"
algorithm = "derivatives"
as = "smooth"
inputs = { time = "/instruments/thermo/temperature/time", values = "/instruments/thermo/temperature/data" }

[[steps]]
action = "run"
algorithm = "derivatives"
as = "rough"
inputs = { time = "/instruments/thermo/temperature/time", values = "/instruments/thermo/temperature/data" }
# splines: the stamps of a live device are not exactly uniform (DeviceClock keeps them causal, so a
# late anchor shortens one interval), which the uniform-sampling methods refuse beyond 5 % on a
# loaded machine
parameters = { lam = 0.0 }

[[steps]]
action = "run"
algorithm = "filter"
inputs = { time = "/instruments/thermo/temperature/time", values = "@smooth/velocity" }
parameters = { method = "smoothing_spline" }
"""


def test_recipe_labels_chain_runs_and_are_checked_at_load(tmp_path: Path, acme_site: Path) -> None:
    recipe = tmp_path / "labels.toml"
    recipe.write_text(LABEL_RECIPE)
    out = tmp_path / "labels.h5"
    proc = run_cli("run", str(recipe), "--out", str(out), "--no-progress", sites=(acme_site,))
    assert proc.returncode == 0, proc.stderr
    with h5py.File(out, "r") as f:
        smooth, rough = f["results/derivatives/run-0001"], f["results/derivatives/run-0002"]
        assert (smooth.attrs["label"], rough.attrs["label"]) == ("smooth", "rough")
        filtered = f["results/filter/run-0001"]
        assert json.loads(filtered.attrs["inputs"])["values"] == "/results/derivatives/run-0001/velocity"
        assert smooth["velocity"].attrs["unit"] == "K/s" and filtered["filtered"].attrs["unit"] == "K/s"
        assert filtered["time"].attrs["unit"] == "s"
    for edit, key, reason in (
            (('as = "rough"', 'as = "smooth"'), "steps.2.as", "run label 'smooth' is already used by steps.1"),
            (('"@smooth/velocity"', '"@later/velocity"', 'as = "rough"', 'as = "later"'), None, None),
            (('as = "smooth"', 'as = "filter"'), "steps.1.as", "'filter' is the name of an algorithm")):
        text = LABEL_RECIPE
        for old, new in zip(edit[::2], edit[1::2], strict=True):
            text = text.replace(old, new)
        recipe.write_text(text)
        check = run_cli("run", str(recipe), "--check", sites=(acme_site,))
        if key is None:  # a label of an earlier step: fine
            assert check.returncode == 0, check.stderr
            continue
        assert check.returncode == 2 and f"{key}: {reason}" in check.stderr, check.stderr
    # steps.1 refers to the label of steps.2, which has not run yet
    text = LABEL_RECIPE.replace('"/instruments/thermo/temperature/data" }\n\n[[steps]]\naction = "run"\n'
                                'algorithm = "derivatives"\nas = "rough"',
                                '"@rough/velocity" }\n\n[[steps]]\naction = "run"\nalgorithm = "derivatives"\n'
                                'as = "rough"', 1)
    assert text != LABEL_RECIPE
    recipe.write_text(text)
    check = run_cli("run", str(recipe), "--check", sites=(acme_site,))
    assert check.returncode == 2 and "steps.1.inputs.values: '@rough/velocity' names the run labelled 'rough' of " \
                                     "steps.2, which has not run yet" in check.stderr, check.stderr


def test_an_analysis_whose_labels_are_taken_stops_before_running(tmp_path: Path, acme_site: Path) -> None:
    """The run steps of the label recipe again on its session: the labels are taken, so nothing runs."""
    recipe, out = tmp_path / "labels.toml", tmp_path / "labels.h5"
    recipe.write_text(LABEL_RECIPE)
    assert run_cli("run", str(recipe), "--out", str(out), "--no-progress", sites=(acme_site,)).returncode == 0
    analysis = tmp_path / "again.toml"
    analysis.write_text(LABEL_RECIPE[LABEL_RECIPE.index('[[steps]]\naction = "run"'):])
    with h5py.File(out, "r") as f:
        before = sorted(f["results/derivatives"]), sorted(f["results/filter"])
    proc = run_cli("run", str(analysis), "--session", str(out), "--no-progress", sites=(acme_site,))
    assert proc.returncode == 2, proc.stderr
    assert "steps.0.as: run label 'smooth' already names /results/derivatives/run-0001 in labels.h5" in proc.stderr
    assert "steps.1.as: run label 'rough' already names /results/derivatives/run-0002" in proc.stderr
    with h5py.File(out, "r") as f:
        assert (sorted(f["results/derivatives"]), sorted(f["results/filter"])) == before


def test_log_and_streams_share_one_time_axis_across_reopenings(tmp_path: Path, registry) -> None:
    path = tmp_path / "clock.h5"
    with Session.create(path, registry=registry) as s:
        s.add_instrument("thermo", "acme_thermometer", simulate=True, simulator={"clock": "FAST"})
        s.record(0.3)
    with h5py.File(path, "r") as f:
        assert f.attrs["clock_origin_utc"] == f.attrs["created_utc"]
        first = schema.read_log(f)
        assert 0 <= first[0]["t"] <= first[-1]["t"] < 60
    with Session.open(path, writable=True, registry=registry) as s:  # a plain reopening continues the axis
        s.write_group("truth/mark", {"x": 1.0})
    with h5py.File(path, "a") as f:  # move the origin an hour back: reopened, the clock must say so
        origin = parse_utc(f.attrs["clock_origin_utc"]) - timedelta(hours=1)
        f.attrs["clock_origin_utc"] = origin.strftime(ISO_FORMAT)
    with Session.open(path, writable=True, registry=registry) as s:
        s.add_instrument("thermo2", "acme_thermometer", simulate=True, simulator={"clock": "FAST"})
        s.record(0.3)
        times, _ = s.stream("thermo2", "temperature")
        old_times, _ = s.stream("thermo", "temperature")
    log = Session.open(path).log()
    t = [e["t"] for e in log]
    assert t == sorted(t)  # one axis: every reopening continues where the last one ended
    started = next(e["t"] for e in log[len(first):] if e["kind"] == "recording_started")
    stopped = next(e["t"] for e in log[len(first):] if e["kind"] == "recording_stopped")
    # the acme driver maps its device clock onto session time: its first sample may precede the event a little
    assert 3600 < started and abs(times[0] - started) < 1 and times[-1] <= stopped < 3700
    assert old_times[-1] < 60


def test_cancelled_run_is_stored_as_cancelled_and_overwrites_nothing(session_file: Path, registry) -> None:
    reported, cancel_sent = threading.Event(), threading.Event()
    outcome: dict[str, Any] = {}

    def progress(done: float, total: float | None, message: str) -> None:
        reported.set()
        assert cancel_sent.wait(30), "the main thread never asked to stop"

    with Session.open(session_file, writable=True, registry=registry) as s:
        first = s.run("acme_drift_rate", INPUTS)
        worker = threading.Thread(target=lambda: outcome.update(ref=s.run("acme_drift_rate", INPUTS, progress=progress,
                                                                          label="stopped")))
        worker.start()
        assert reported.wait(30)
        s.request_stop()
        cancel_sent.set()
        worker.join(30)
        assert not worker.is_alive()
        ref = outcome["ref"]
        assert (ref.status, ref.error, ref.label) == ("cancelled", "stopped on request", "stopped")
        assert s.members(ref.path) == [] and s.attributes(ref.path)["status"] == "cancelled"
        assert s.resolve("@acme_drift_rate/rate") == f"{first.path}/rate"  # the earlier run still answers
        with pytest.raises(ValidationError, match="no successful run of 'stopped'"):
            s.resolve("@stopped/rate")
    with Session.open(session_file) as s:
        (event,) = [e for e in s.log() if e["kind"] == "result_written" and "cancelled" in e["message"]]
        assert event["level"] == "warning" and event["data"] == {"label": "stopped"}
        assert [r.status for r in s.results()] == ["ok", "cancelled"]


class Extra(Algorithm):
    name = "extra"
    version = "1.0.0"
    description = "returns an output it does not declare"
    outputs = (Port("a", "() declared", "mm"),)

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict:
        return {"a": 1.0, "b": 2.0}


class Dates(Algorithm):
    name = "dates"
    version = "1.0.0"
    description = "returns a value HDF5 cannot store"
    outputs = (Port("when", "() a date"),)

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict:
        return {"when": np.datetime64("2026-11-23")}


@pytest.mark.parametrize(("algorithm", "error"), [
    (Extra, "extra returned undeclared output(s) b; declare each as a Port in extra.outputs"),
    (Dates, "dates returned output(s) HDF5 cannot store: when (datetime64[D])"),
])
def test_outputs_without_a_declaration_or_a_storable_type_fail_cleanly(algorithm: type[Algorithm], error: str,
                                                                       session_file: Path, registry) -> None:
    with Session.open(session_file, writable=True, registry=registry) as s:
        ref = s.run(algorithm, {})
        assert ref.status == "failed" and ref.error.startswith(error) and s.members(ref.path) == []


def test_execute_reports_cancellation_at_the_first_check() -> None:
    cancel = threading.Event()
    calls: list[float] = []

    def progress(done: float, total: float | None, message: str) -> None:
        calls.append(done)
        cancel.set()

    from mirrorlab.core.registry import get_registry
    out = execute(get_registry().algorithm("derivatives"), {"time": T, "values": np.stack([KELVIN] * 90, 1)}, {},
                  RunContext(progress, cancel))
    assert (out.status, out.error, out.outputs, calls) == ("cancelled", "stopped on request", {}, [0])


def test_every_builtin_output_is_described_and_its_unit_placeholders_name_inputs() -> None:
    from mirrorlab.core.registry import get_registry
    reg = get_registry(refresh=True)
    for name in reg.names("algorithm"):
        cls = reg.algorithm(name)
        inputs = {p.name for p in cls.inputs}
        for port in cls.outputs:
            assert port.description.strip(), f"{name}.{port.name} has no description"
            assert set(re.findall(r"\{(\w+)\}", port.unit)) <= inputs, f"{name}.{port.name}: {port.unit}"


def write_v1_session(path: Path) -> None:
    """A schema 1 session as the v1 code wrote it (docs/session-format.md of schema 1): no clock
    origin, no /controllers, a run with ``status`` among its first attributes and ``"<array>"``
    inputs, log times from 0 at the opening."""
    with h5py.File(path, "w", libver=schema.LIBVER) as f:
        f.attrs.update({"mirrorlab_schema": 1, "mirrorlab_version": "0.1.0", "session_id": "0" * 36,
                        "created_utc": "2026-11-20T10:00:00.000000Z", "operator": "ana",
                        "description": "a schema 1 file", "status": "closed"})
        for name in ("config", "instruments", "calibration", "results", "truth"):
            f.create_group(name)
        f["config"].create_dataset("recipe", data="", dtype=schema.STR)
        f["config"].create_dataset("provenance", data="{}", dtype=schema.STR)
        g = f["instruments"].create_group("thermo")
        g.attrs.update({"plugin": "acme_thermometer", "version": "0.3.0", "port": "", "simulated": True,
                        "settings": '{"rate": 100.0}', "identity": "{}", "firmware": "", "reconnects": 0})
        st = g.create_group("temperature")
        st.create_dataset("data", data=KELVIN, maxshape=(None,), chunks=(100,))
        st.create_dataset("time", data=T, maxshape=(None,), chunks=(1024,))
        st.attrs.update({"unit": "K", "time_unit": "s", "rate": 10.0, "description": "temperature", "dropped": 0})
        run = f.create_group("results/acme_drift_rate/run-0001")
        run.attrs.update({"algorithm": "acme_drift_rate", "plugin_version": "0.3.0", "status": "ok", "error": "",
                          "started_utc": "2026-11-20T10:00:01.000000Z", "finished_utc": "2026-11-20T10:00:01.100000Z",
                          "parameters": '{"skip": 0.0}', "inputs": '{"time": "<array>", "values": "<array>"}'})
        run.create_dataset("rate", data=0.005)
        log = schema.create_log(f)
        schema.append(log, np.array([(0.0, b"info", b"session", b"closed", b"session closed", b"{}")],
                                    dtype=schema.LOG_DTYPE))


def test_schema_1_files_still_open_read_and_take_results(tmp_path: Path, registry, acme_site: Path) -> None:
    path = tmp_path / "v1.h5"
    write_v1_session(path)
    for command in ("info", "check"):
        proc = run_cli("session", command, str(path), sites=(acme_site,))
        assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "complete (status 'closed', schema 1)" in proc.stdout
    with Session.open(path, writable=True, registry=registry) as s:
        assert [(r.path, r.status, r.label) for r in s.results()] == [("/results/acme_drift_rate/run-0001", "ok", "")]
        assert s.resolve("@acme_drift_rate/rate") == "/results/acme_drift_rate/run-0001/rate"
        ref = s.run("acme_drift_rate", {"time": "/instruments/thermo/temperature/time",
                                        "values": "/instruments/thermo/temperature/data"}, label="v2_run")
        assert s.clock.now() < 60  # no stored origin: this opening starts at 0, as schema 1 did
    with h5py.File(path, "r") as f:
        assert f.attrs["mirrorlab_schema"] == 1 and "clock_origin_utc" not in f.attrs and "controllers" not in f
        assert f[ref.path]["rate"].attrs["unit"] == "K/s" and f[ref.path].attrs["status"] == "ok"
    info = run_cli("session", "info", str(path), sites=(acme_site,))
    assert "clock_origin_utc" not in info.stdout and "mirrorlab_schema: 1" in info.stdout
    assert "result /results/acme_drift_rate/run-0002 as 'v2_run': ok" in info.stdout
    assert run_cli("session", "check", str(path)).returncode == 0


def test_analyze_takes_a_label_and_prints_units(session_file: Path, acme_site: Path) -> None:
    proc = run_cli("analyze", "acme_drift_rate", str(session_file), "--input", "time=/truth/thermo/time",
                   "--input", "values=/truth/thermo/data", "--as", "first", "--no-progress", sites=(acme_site,))
    assert proc.returncode == 0, proc.stderr
    assert "/results/acme_drift_rate/run-0001 (@first): ok" in proc.stdout
    assert "/results/acme_drift_rate/run-0001/rate: () float64 [K/s]" in proc.stdout
    again = run_cli("analyze", "acme_drift_rate", str(session_file), "--input", "time=/truth/thermo/time",
                    "--input", "values=@first/rate", "--as", "first", "--no-progress", sites=(acme_site,))
    assert again.returncode == 2 and "label 'first' already names /results/acme_drift_rate/run-0001" in again.stderr
    data = json.loads(run_cli("session", "info", str(session_file), "--json", sites=(acme_site,)).stdout)
    (result,) = data["results"]
    assert result["label"] == "first" and result["outputs"]["rate"] == {"shape": [], "dtype": "float64",
                                                                          "unit": "K/s"}


def test_every_top_level_group_is_documented() -> None:
    doc = (Path(__file__).parents[2] / "docs" / "session-format.md").read_text()
    for name in (*schema.GROUPS, *schema.PLUGIN_GROUPS, "log"):
        assert f"## /{name}" in doc or f"| `/{name}" in doc, f"/{name} is not described in docs/session-format.md"
