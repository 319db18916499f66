"""Stored output units are units, never an unfilled ``{input}`` template.

An algorithm may declare an output unit as ``{values}/s``: the unit of its input ``values`` per
second, filled in by ``Session.run``. Over every registered algorithm: each placeholder names an
input, and a run on representative inputs (datasets with a unit, and arrays with ``input_units``)
stores units without ``{`` that pint understands. Through the CLI: ``kinematics derivatives`` on a
session stores ``mm``, ``mm/s``, ``mm/s²``, and ``session info`` prints them.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from mirrorlab.core import Session, get_registry
from mirrorlab.core.params import check_unit
from mirrorlab.plugins.kinematics import write_c3d

from tests.support import run_cli

PLACEHOLDER = re.compile(r"\{(\w+)\}")


def _series() -> dict[str, np.ndarray]:
    t = np.arange(40) / 50.0
    return {"time": t, "values": np.stack([np.sin(3 * t), np.cos(2 * t)], axis=-1)[:, None, :] * 100.0}


#: Inputs of a run of each algorithm whose outputs have templated units.
REPRESENTATIVE: dict[str, Callable[[], dict[str, np.ndarray]]] = {"derivatives": _series, "filter": _series}


def _templated() -> dict[str, type]:
    reg = get_registry()
    classes = {name: reg.algorithm(name) for name in reg.names("algorithm")}
    return {n: c for n, c in classes.items() if any(PLACEHOLDER.search(p.unit) for p in c.outputs)}


def test_every_placeholder_of_every_algorithm_names_one_of_its_inputs() -> None:
    reg = get_registry()
    names = reg.names("algorithm")
    assert "derivatives" in names and len(names) > 20
    for name in names:
        cls = reg.algorithm(name)
        inputs = {p.name for p in cls.inputs}
        for port in cls.outputs:
            refs = set(PLACEHOLDER.findall(port.unit))
            assert refs <= inputs, f"{name}.{port.name}: {port.unit!r} names no input {refs - inputs}"
            if refs:
                check_unit(PLACEHOLDER.sub("mm", port.unit))  # what it becomes for an input in mm


def test_every_templated_algorithm_stores_resolved_units(tmp_path: Path) -> None:
    templated = _templated()
    assert set(templated) == set(REPRESENTATIVE), "give representative inputs for every templated algorithm"
    with Session.create(tmp_path / "s.h5") as s:
        for name, cls in templated.items():
            arrays = REPRESENTATIVE[name]()
            units = {p.name: p.unit or "mm" for p in cls.inputs if p.name in arrays}
            for port, a in arrays.items():
                s.write_group(f"inputs/{name}/{port}", {"data": a}, {"unit": units[port]})
            from_datasets = s.run(cls, {p: f"/inputs/{name}/{p}/data" for p in arrays})
            from_arrays = s.run(cls, arrays, input_units=units)
            for ref in (from_datasets, from_arrays):
                assert ref.status == "ok", ref.error
                stored = {k: s.attributes(f"{ref.path}/{k}")["unit"] for k in s.members(ref.path)}
                for port in cls.outputs:
                    expect = PLACEHOLDER.sub(lambda m, units=units: units[m[1]], port.unit)
                    assert stored[port.name] == expect and "{" not in expect, (name, port.name, stored[port.name])
                    check_unit(expect)


def _trial(tmp_path: Path) -> Path:
    t = np.arange(30) / 100.0
    pts = np.stack([np.c_[100 * t, 0 * t, 0 * t], np.c_[0 * t, 50 * t ** 2, 0 * t], np.c_[t, t, t]], axis=1)
    path = tmp_path / "trial.c3d"
    write_c3d(path, ["A", "B", "C"], 100.0, pts)
    return path


def _units(session: Path) -> list[dict[str, str]]:
    with h5py.File(session, "r") as f:
        runs = f["results/derivatives"]
        return [{k: runs[r][k].attrs["unit"] for k in runs[r]} for r in sorted(runs)]


MM = {"smoothed": "mm", "velocity": "mm/s", "acceleration": "mm/s²"}


def test_kinematics_derivatives_store_mm_per_s_and_session_info_prints_them(tmp_path: Path) -> None:
    session = tmp_path / "s.h5"
    assert run_cli("kinematics", "import", str(_trial(tmp_path)), "--session", str(session)).returncode == 0
    for extra in ((), ("--markers", "A,B")):  # the marker set's datasets, and a subset passed as an array
        proc = run_cli("kinematics", "derivatives", str(session), *extra, "--no-progress")
        assert proc.returncode == 0, proc.stderr
    proc = run_cli("analyze", "derivatives", str(session), "--input", "time=/markers/trial/time",
                   "--input", "values=/markers/trial/points")  # the core command: units from the datasets
    assert proc.returncode == 0, proc.stderr
    assert _units(session) == [MM, MM, MM]
    info = run_cli("session", "info", str(session))
    assert info.returncode == 0 and "{" not in info.stdout
    assert "acceleration: 30×3×3 float64 [mm/s²]" in info.stdout and "velocity: 30×2×3 float64 [mm/s]" in info.stdout


def test_a_session_imported_before_the_unit_attribute_resolves_too(tmp_path: Path) -> None:
    session = tmp_path / "old.h5"
    assert run_cli("kinematics", "import", str(_trial(tmp_path)), "--session", str(session)).returncode == 0
    with h5py.File(session, "r+") as f:
        del f["markers/trial"].attrs["unit"]  # as written before: only @units
    proc = run_cli("kinematics", "derivatives", str(session), "--no-progress")
    assert proc.returncode == 0, proc.stderr
    assert _units(session) == [MM]


@pytest.mark.parametrize("unit", ["K", "V"])
def test_a_stream_in_another_unit_gets_that_unit(tmp_path: Path, unit: str) -> None:
    data = _series()
    with Session.create(tmp_path / "s.h5") as s:
        ref = s.run("derivatives", data, input_units={"values": unit, "time": "s"})
        assert s.attributes(f"{ref.path}/acceleration")["unit"] == f"{unit}/s²"
