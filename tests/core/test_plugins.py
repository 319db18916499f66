"""Plugin discovery: built-ins, a real installed third-party plugin, broken and clashing plugins."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from mirrorlab.core import DuplicateNameError, Session
from mirrorlab.core.registry import get_registry

from tests.support import run_cli


def test_builtins_are_registered() -> None:
    reg = get_registry(refresh=True)
    assert {"acquire", "wait", "run"} <= set(reg.names("step"))
    assert "film_scanner" in reg.names("instrument")
    assert not reg.broken, [(p.name, p.error) for p in reg.broken]


def test_installed_thirdparty_plugin_is_discovered(acme_site: Path, with_sites) -> None:
    reg = with_sites(acme_site)
    assert reg.instrument("acme_thermometer").version == "0.3.0"
    assert reg.algorithm("acme_drift_rate").name == "acme_drift_rate"
    info = reg.provider("instrument", "acme_thermometer")
    assert info.distribution == "mirrorlab-acme" and info.version == "0.3.0"
    assert info.source == "acme = acme_mirrorlab.plugin"


def test_plugins_json_lists_builtins_and_thirdparty(acme_site: Path) -> None:
    proc = run_cli("plugins", "--json", sites=(acme_site,))
    assert proc.returncode == 0, proc.stderr
    data = json.loads(proc.stdout)
    names = {i["name"]: i for i in data["instruments"]}
    assert {"film_scanner", "acme_thermometer"} <= set(names)
    rate = names["acme_thermometer"]["parameters"][0]
    assert rate == {"name": "rate", "type": "float", "default": 10.0, "unit": "Hz", "bounds": [1.0, 1000.0],
                    "choices": None, "help": "samples per second", "required": False, "live": False,
                    "shape": None}
    assert "acme_drift_rate" in {a["name"] for a in data["algorithms"]}


def test_broken_plugin_is_reported_and_others_keep_working(acme_site: Path, broken_site: Path,
                                                           with_sites, tmp_path: Path) -> None:
    reg = with_sites(acme_site, broken_site)
    broken = {p.name: p for p in reg.broken}
    assert "broken_import" in broken
    assert "No module named 'mirrorlab_nonexistent_dependency'" in broken["broken_import"].error
    assert "Traceback" in broken["broken_import"].traceback
    # the clash: both providers named, the name refused, everything else usable
    with pytest.raises(DuplicateNameError) as info:
        reg.algorithm("acme_drift_rate")
    message = str(info.value)
    assert "acme (acme = acme_mirrorlab.plugin)" in message and "clash (clash = broken_mirrorlab.clash)" in message
    assert reg.instrument("acme_thermometer") is not None
    with Session.create(tmp_path / "s.h5", registry=reg) as s:
        s.add_instrument("t", "acme_thermometer", simulate=True, simulator={"clock": "FAST"})

    doctor = run_cli("plugins", "doctor", sites=(acme_site, broken_site))
    assert doctor.returncode == 1
    assert "broken_import [BROKEN]" in doctor.stdout
    assert "CONFLICT: the algorithm name 'acme_drift_rate' is provided by both" in doctor.stdout
    listing = run_cli("plugins", sites=(acme_site, broken_site))
    assert listing.returncode == 0 and "BROKEN broken_import" in listing.stdout
    assert "acme_thermometer" in listing.stdout


def test_plugins_show_prints_typed_parameters(acme_site: Path) -> None:
    proc = run_cli("plugins", "show", "acme_thermometer", sites=(acme_site,))
    assert proc.returncode == 0, proc.stderr
    assert "rate" in proc.stdout and "Hz" in proc.stdout and "1.0..1000.0" in proc.stdout
    missing = run_cli("plugins", "show", "nope")
    assert missing.returncode == 2 and "nothing named 'nope'" in missing.stderr


def test_add_plugin_at_run_time_all_or_nothing() -> None:
    from mirrorlab.core import Algorithm, PluginError, hookimpl
    from mirrorlab.core.registry import Registry

    class Ok(Algorithm):
        name, version, description = "inline_ok", "1.0", "inline algorithm"

        def run(self, inputs, params, context):
            return {}

    class HalfBroken:
        @hookimpl
        def mirrorlab_register_algorithms(self):
            return [Ok]

        @hookimpl
        def mirrorlab_register_steps(self):
            raise RuntimeError("step table corrupt")

    reg = Registry(entry_points=False)
    info = reg.add_plugin(HalfBroken(), "half")
    assert not info.ok and "step table corrupt" in info.error
    with pytest.raises(PluginError, match="no algorithm named 'inline_ok'"):
        reg.algorithm("inline_ok")  # nothing of a broken plugin is usable
    class Fine:
        @hookimpl
        def mirrorlab_register_algorithms(self):
            return [Ok]

    assert reg.add_plugin(Fine(), "fine").ok and reg.algorithm("inline_ok") is Ok
    with pytest.raises(PluginError, match="already registered"):
        reg.add_plugin(Fine(), "fine")
