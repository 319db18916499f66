"""The Session API: instruments, recording, live subscriptions, results and their provenance."""

from __future__ import annotations

import json
import threading
from pathlib import Path

import h5py
import numpy as np
import pytest
from mirrorlab.core import PluginError, Session, SessionError, ValidationError

TIME = "/instruments/thermo/temperature/time"
VALUES = "/instruments/thermo/temperature/data"


@pytest.fixture
def registry(acme_site: Path, with_sites):
    return with_sites(acme_site)


@pytest.fixture
def recorded(tmp_path: Path, registry) -> Path:
    path = tmp_path / "s.h5"
    with Session.create(path, operator="ana", description="unit test", registry=registry) as s:
        s.add_instrument("thermo", "acme_thermometer", simulate=True, settings={"rate": 100})
        live = s.subscribe("thermo", "temperature")
        stats = s.record(1.0)
        blocks = live.drain()
    assert stats["thermo/temperature"]["dropped"] == 0
    assert sum(len(b.times) for b in blocks) == stats["thermo/temperature"]["samples"] > 50
    return path


def test_file_layout_and_attributes(recorded: Path) -> None:
    with h5py.File(recorded, "r") as f:
        a = f.attrs
        assert a["mirrorlab_schema"] == 2 and a["status"] == "closed" and a["operator"] == "ana"
        assert len(a["session_id"]) == 36 and a["created_utc"].endswith("Z")
        assert a["clock_origin_utc"] == a["created_utc"]
        assert {"config", "instruments", "controllers", "calibration", "results", "truth", "log"} <= set(f)
        prov = json.loads(f["config/provenance"][()])
        assert prov["packages"]["h5py"] and "acme" in prov["plugins"]
        g = f["instruments/thermo"]
        assert g.attrs["plugin"] == "acme_thermometer" and g.attrs["firmware"] == "2.1"
        assert json.loads(g.attrs["settings"]) == {"rate": 100.0}
        assert g["temperature/data"].chunks is not None and g["temperature"].attrs["unit"] == "K"
        assert g["temperature/data"].maxshape == (None,)


def _slope_tolerance(times: np.ndarray) -> float:
    """Five standard errors of a least-squares slope through the simulated thermometer's samples
    (K/s): its noise is 1 mK Gaussian, sent rounded to whole mK (+1/12 mK² of variance). The number
    of samples a 1 s recording gets depends on the machine, so the bound is computed from them."""
    sigma = 1e-3 * np.sqrt(1.0 + 1.0 / 12.0)
    return 5.0 * sigma / np.sqrt(np.sum((times - times.mean()) ** 2))


def test_recorded_stream_matches_the_simulated_drift(recorded: Path) -> None:
    with Session.open(recorded) as s:
        times, values = s.stream("thermo", "temperature")
        slope = np.polyfit(times, values, 1)[0]
    assert np.all(np.diff(times) > 0)
    # the model drifts 5 mK/s; the former rel=0.2 was under 3 standard errors of a 1 s recording
    assert slope == pytest.approx(0.005, abs=_slope_tolerance(times))


def test_results_are_never_overwritten_and_failures_are_kept(recorded: Path, registry) -> None:
    with Session.open(recorded, writable=True, registry=registry) as s:
        first = s.run("acme_drift_rate", {"time": TIME, "values": VALUES})
        second = s.run("acme_drift_rate", {"time": TIME, "values": VALUES}, {"skip": "200 ms"})
        failed = s.run("acme_drift_rate", {"time": np.zeros(1), "values": np.zeros(1)})
    assert [first.run_id, second.run_id, failed.run_id] == ["run-0001", "run-0002", "run-0003"]
    with Session.open(recorded) as s:
        r1, r2, r3 = (s.result(r) for r in (first, second, failed))
        assert r1.attrs["status"] == "ok" and r1.attrs["parameters"] == {"skip": 0.0}
        assert r2.attrs["parameters"] == {"skip": 0.2} and r2.attrs["inputs"] == {"time": TIME, "values": VALUES}
        assert r1.outputs["rate"] == pytest.approx(0.005, abs=_slope_tolerance(s.read(TIME)))   # as above
        assert r3.ref.status == "failed" and "need at least 2 samples" in r3.attrs["error"]
        assert r1.attrs["plugin_version"] == "0.3.0" and r1.attrs["finished_utc"] >= r1.attrs["started_utc"]
        kinds = [e["kind"] for e in s.log()]
    assert kinds.count("result_written") == 3 and "recording_started" in kinds


def test_read_only_by_default(recorded: Path) -> None:
    with Session.open(recorded) as s:
        with pytest.raises(SessionError, match="read-only"):
            s.run("acme_drift_rate", {"time": TIME, "values": VALUES})


def test_parameter_and_input_errors_are_specific(recorded: Path, registry) -> None:
    with Session.open(recorded, writable=True, registry=registry) as s:
        with pytest.raises(ValidationError, match="skip: -1.0 s is below the minimum 0.0 s"):
            s.run("acme_drift_rate", {"time": TIME, "values": VALUES}, {"skip": -1})
        with pytest.raises(ValidationError, match="no dataset '/nope'"):
            s.run("acme_drift_rate", {"time": "/nope", "values": VALUES})
        with pytest.raises(PluginError, match="no algorithm named 'nope'; installed: acme_drift_rate"):
            s.run("nope", {})


def test_exception_inside_a_session_marks_it_aborted(tmp_path: Path, registry) -> None:
    path = tmp_path / "a.h5"
    with pytest.raises(RuntimeError):
        with Session.create(path, registry=registry) as s:
            s.add_instrument("thermo", "acme_thermometer", simulate=True)
            s.record(0.2)
            raise RuntimeError("operator pressed stop")
    with Session.open(path) as s:
        assert s.status == "aborted" and s.stream("thermo", "temperature").data.size > 0
    # before anything was recorded there is nothing to keep: no file (see test_failed_start.py)
    with pytest.raises(RuntimeError):
        with Session.create(tmp_path / "b.h5", registry=registry) as s:
            s.add_instrument("thermo", "acme_thermometer", simulate=True)
            raise RuntimeError("operator pressed stop")
    assert not (tmp_path / "b.h5").exists()


def test_instrument_errors(tmp_path: Path, registry) -> None:
    with Session.create(tmp_path / "e.h5", registry=registry) as s:
        with pytest.raises(ValidationError, match="rate: 5000.0 Hz is above the maximum 1000.0 Hz"):
            s.add_instrument("t", "acme_thermometer", simulate=True, settings={"rate": 5000})
        with pytest.raises(PluginError, match="no instrument named 'camera9'"):
            s.add_instrument("t", "camera9", simulate=True)
        s.add_instrument("t", "acme_thermometer", simulate=True)
        with pytest.raises(SessionError, match="already in this session"):
            s.add_instrument("t", "acme_thermometer", simulate=True)
        s.write_group("calibration/t", {"k": np.eye(3)}, {"rms_px": 0.2})
        with pytest.raises(SessionError, match="never overwritten"):
            s.write_group("calibration/t", {"k": np.eye(3)})
    with pytest.raises(SessionError, match="already exists"):
        Session.create(tmp_path / "e.h5", registry=registry)


def test_recording_survives_a_device_disconnect(tmp_path: Path, registry) -> None:
    path = tmp_path / "r.h5"
    with Session.create(path, registry=registry) as s:
        s.add_instrument("thermo", "acme_thermometer", simulate=True, settings={"rate": 100},
                         simulator={"transport": "tcp"})
        reconnected = threading.Event()
        s.events.subscribe(lambda e: reconnected.set() if e.kind == "reconnected" else None)
        live = s.subscribe("thermo", "temperature")
        s.start_recording()
        assert live.get(timeout=60) is not None  # recording, then unplug
        s.simulator("thermo").disconnect()
        assert reconnected.wait(60), "no reconnect"
        after = s.clock.now()
        while (block := live.get(timeout=60)) is not None and block.times[-1] <= after:
            pass  # waiting for a sample taken after the reconnect
        s.stop_recording()
    with Session.open(path) as s:
        kinds = [e["kind"] for e in s.log()]
        times, _ = s.stream("thermo", "temperature")
        assert s.attributes("instruments/thermo")["reconnects"] >= 1
    assert "connection_lost" in kinds and "reconnected" in kinds
    assert times.max() > after  # samples after the reconnect were recorded


def test_analysis_keeps_an_aborted_status(tmp_path: Path, registry) -> None:
    path = tmp_path / "ab.h5"
    with pytest.raises(RuntimeError):
        with Session.create(path, registry=registry) as s:
            s.add_instrument("thermo", "acme_thermometer", simulate=True, settings={"rate": 100})
            s.record(0.5)
            raise RuntimeError("stopped by the operator")
    with Session.open(path, writable=True, registry=registry) as s:
        assert s.run("acme_drift_rate", {"time": TIME, "values": VALUES}).status == "ok"
    with Session.open(path) as s:
        assert s.status == "aborted" and len(s.results()) == 1


def test_record_a_subset_and_until_sources_end(tmp_path: Path, registry) -> None:
    path = tmp_path / "sub.h5"
    with Session.create(path, registry=registry) as s:
        s.add_instrument("a", "acme_thermometer", simulate=True, settings={"rate": 100})
        s.add_instrument("b", "acme_thermometer", simulate=True, settings={"rate": 100})
        s.record(0.5, instruments=["a"])
        with pytest.raises(SessionError, match="cannot record c"):
            s.start_recording(["c"])
        # a finite source: 5 virtual-lab frames, recorded until it ends (no duration given)
        s.add_instrument("cam", "film_scanner", settings={"source": "virtual", "scene": "rssr",
                                                          "scene_frames": 5, "frame_rate": 50.0})
        s.record(None, instruments=["cam"])
    with Session.open(path) as s:
        assert s.stream("a", "temperature").data.size > 20
        assert "temperature" not in s.members("instruments/b")
        assert s.stream("cam", "frame_index").data.tolist() == [0, 1, 2, 3, 4]
        assert s.exists("truth/cam")


def test_results_chain_through_references(tmp_path: Path, registry) -> None:
    t = np.linspace(0, 1, 101)
    with Session.create(tmp_path / "chain.h5", registry=registry) as s:
        s.write_group("truth/x", {"t": t, "x": t ** 3})
        with pytest.raises(ValidationError, match="no successful run of 'derivatives'"):
            s.run("derivatives", {"time": "/truth/x/t", "values": "@derivatives/velocity"})
        s.run("derivatives", {"time": "/truth/x/t", "values": "/truth/x/x"}, {"method": "smoothing_spline"})
        ref = s.run("derivatives", {"time": "/truth/x/t", "values": "@derivatives/velocity"})
        out = s.result(ref)
    assert out.attrs["inputs"]["values"] == "/results/derivatives/run-0001/velocity"
    # the velocity of the velocity of t³, both by GCV splines of noise-free data (lambda near 0, where
    # scipy's bounded search stops): a method bound of 0.3 % of the 6 mm/s² · t range, not rounding
    np.testing.assert_allclose(out.outputs["velocity"][20:-20], 6 * t[20:-20], atol=2e-2)

