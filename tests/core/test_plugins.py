"""Plugin discovery: built-ins, a real installed third-party plugin, broken and clashing plugins."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pytest
from mirrorlab.core import DuplicateNameError, Session
from mirrorlab.core.registry import get_registry

from tests.support import pip_install_target, run_cli


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
    # a class of the wrong kind: rejected at discovery, one line naming the plugin
    assert "wrong_kind [BROKEN]" in doctor.stdout
    assert ("    error: plugin 'wrong_kind': mirrorlab_register_instruments returned "
            "broken_mirrorlab.wrong_kind.NotAnInstrument, which is an algorithm; instruments subclass "
            "mirrorlab.core.devices.Instrument\n") in doctor.stdout
    assert "not_an_instrument" not in reg.names("instrument") and "not_an_instrument" not in reg.names("algorithm")
    # an instrument that needs a port but cannot make a simulator
    assert "no_simulator [PROBLEM]" in doctor.stdout and "    simulator for unsimulated: no" in doctor.stdout
    assert "problem: instrument 'unsimulated' needs a port but cannot make a simulator" in doctor.stdout
    listing = run_cli("plugins", sites=(acme_site, broken_site))
    assert listing.returncode == 0 and "BROKEN broken_import" in listing.stdout
    assert "acme_thermometer" in listing.stdout


def test_plugins_show_prints_typed_parameters(acme_site: Path) -> None:
    proc = run_cli("plugins", "show", "acme_thermometer", sites=(acme_site,))
    assert proc.returncode == 0, proc.stderr
    assert "rate" in proc.stdout and "Hz" in proc.stdout and "1.0..1000.0" in proc.stdout
    missing = run_cli("plugins", "show", "nope")
    assert missing.returncode == 2 and "nothing named 'nope'" in missing.stderr


def test_plugins_show_every_kind_with_the_name() -> None:
    """`retarget` is an algorithm, a controller and a step: all three are shown, or the one --kind picks."""
    proc = run_cli("plugins", "show", "retarget")
    assert proc.returncode == 0, proc.stderr
    heads = [line.split()[0] for line in proc.stdout.splitlines() if line.split()[1:2] == ["retarget"]]
    assert heads == ["algorithm", "controller", "step"]
    one = run_cli("plugins", "show", "retarget", "--kind", "controller")
    assert one.stdout.startswith("controller retarget") and "  settings:" in one.stdout
    assert "\nalgorithm " not in one.stdout
    none = run_cli("plugins", "show", "retarget", "--kind", "instrument")
    assert none.returncode == 2 and "no instrument named 'retarget'" in none.stderr


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
    assert not info.ok and info.error == "plugin 'half': mirrorlab_register_steps failed: RuntimeError: step table corrupt"
    assert not reg.pm.has_plugin("half")  # its lifecycle hooks are not called either
    with pytest.raises(PluginError, match="no algorithm named 'inline_ok'"):
        reg.algorithm("inline_ok")  # nothing of a broken plugin is usable
    class Fine:
        @hookimpl
        def mirrorlab_register_algorithms(self):
            return [Ok]

    assert reg.add_plugin(Fine(), "fine").ok and reg.algorithm("inline_ok") is Ok
    with pytest.raises(PluginError, match="already registered"):
        reg.add_plugin(Fine(), "fine")


def _algorithm(name: str) -> type:
    from mirrorlab.core import Algorithm

    return type(name, (Algorithm,), {"name": name, "version": "1.0", "description": f"inline {name}",
                                     "run": lambda self, inputs, params, context: {}})


def test_registration_hooks_are_called_through_pluggy() -> None:
    """Only marked functions count; tryfirst orders the providers; a hook wrapper wraps every plugin's list."""
    import pluggy
    from mirrorlab.core import hookimpl
    from mirrorlab.core.registry import Registry

    first, second, unmarked = _algorithm("shared"), _algorithm("shared"), _algorithm("unmarked")

    class Unmarked:
        def mirrorlab_register_algorithms(self):  # no @hookimpl: not a hook implementation
            return [unmarked]

    class Late:
        @hookimpl
        def mirrorlab_register_algorithms(self):
            return [second]

    class Early:
        @hookimpl(tryfirst=True)
        def mirrorlab_register_algorithms(self):
            return [first]

    seen: list[list[str]] = []

    class Wrapper:  # e.g. a site policy: drop algorithms whose name starts with "x_"
        @hookimpl(wrapper=True)
        def mirrorlab_register_algorithms(self):
            classes = yield
            seen.append([c.name for result in classes for c in result])
            return [[c for c in result if not c.name.startswith("x_")] for result in classes]

    reg = Registry(entry_points=False, builtins=False)
    assert reg.add_plugin(Unmarked(), "unmarked").ok and reg.names("algorithm") == []
    reg.add_plugin(Wrapper(), "wrapper")
    assert reg.add_plugin(Late(), "late").ok and reg.add_plugin(Early(), "early").ok
    # pluggy's order (tryfirst first) decides the order of the providers, whatever the loading order
    assert [p.plugin for p in reg.providers("algorithm", "shared")] == ["early", "late"]
    hidden = _algorithm("x_hidden")

    class Hidden:
        @hookimpl
        def mirrorlab_register_algorithms(self):
            return [hidden, _algorithm("kept")]

    assert reg.add_plugin(Hidden(), "hidden").ok
    assert "x_hidden" not in reg.names("algorithm") and reg.provider("algorithm", "kept").name == "hidden"
    assert seen[-1] == ["x_hidden", "kept"]
    assert isinstance(reg.pm, pluggy.PluginManager)


@pytest.mark.parametrize(("hook", "returned", "message"), [
    ("mirrorlab_register_instruments", "algorithm",
     "plugin 'bad': mirrorlab_register_instruments returned tests.core.test_plugins.wrong, which is an algorithm; "
     "instruments subclass mirrorlab.core.devices.Instrument"),
    ("mirrorlab_register_steps", "plain",
     "plugin 'bad': mirrorlab_register_steps returned tests.core.test_plugins.wrong, which is not a step; "
     "steps subclass mirrorlab.core.steps.Step"),
    ("mirrorlab_register_controllers", "instance",
     "plugin 'bad': mirrorlab_register_controllers returned 3, which is not a class"),
])
def test_a_class_of_the_wrong_kind_is_rejected_naming_the_plugin(hook: str, returned: str, message: str) -> None:
    from mirrorlab.core import hookimpl
    from mirrorlab.core.registry import Registry

    wrong = {"algorithm": _algorithm("wrong"), "plain": type("wrong", (), {"name": "wrong"}), "instance": 3}[returned]
    if isinstance(wrong, type):
        wrong.__module__, wrong.__qualname__ = __name__, "wrong"
    plugin = type("Bad", (), {hook: hookimpl(lambda self: [wrong])})()
    reg = Registry(entry_points=False, builtins=False)
    info = reg.add_plugin(plugin, "bad")
    assert info.error == message and "\n" not in info.error


def test_registry_isolation_flags(acme_site: Path, with_sites) -> None:
    """``builtins`` / ``entry_points`` select the mirrorlab distribution's entry points / everyone else's."""
    from mirrorlab.core.registry import Registry

    with_sites(acme_site)
    builtin_only = Registry(entry_points=False)
    assert "film_scanner" in builtin_only.names("instrument") and "acme_thermometer" not in builtin_only.names("instrument")
    assert {p.distribution for p in builtin_only.plugins.values()} == {"mirrorlab"}
    third_party = Registry(builtins=False)
    assert third_party.names("instrument") == ["acme_thermometer"]
    assert Registry(entry_points=False, builtins=False).plugins == {}


def test_make_simulator_is_part_of_the_instrument_base_class() -> None:
    from mirrorlab.core import PluginError
    from mirrorlab.core.devices import LineSimulator, SerialInstrument
    from mirrorlab.core.params import Parameter, ParameterSet
    from mirrorlab.instruments.film_scanner import FilmScanner

    class Model(LineSimulator):
        pass

    class Simulated(SerialInstrument):
        name, version, description = "simulated", "1.0", "a device with a simulator class"
        simulator = Model

    class Real(SerialInstrument):
        name, version, description = "real", "1.0", "a device without simulator"
        parameters = ParameterSet(Parameter("port_kind", str, "usb", help="how it is attached"))

    model = Simulated.make_simulator({}, seed=7)
    assert type(model) is Model and model.seed == 7 and Simulated.has_simulator()
    class Custom(Real):  # builds its model from the settings
        @classmethod
        def make_simulator(cls, settings, seed):
            return Model(seed=seed + len(settings))

    assert Custom.has_simulator() and Custom.make_simulator({"a": 1}, seed=1).seed == 2
    assert FilmScanner.has_simulator()
    assert not Real.has_simulator()
    with pytest.raises(PluginError, match="instrument plugin 'real' has no simulator; set simulate = false"):
        Real.make_simulator({}, seed=0)


LAZY_PLUGIN = '''
from mirrorlab.core import Algorithm, ParameterSet, hookimpl


def _algorithm(name):
    return type(name, (Algorithm,), {"name": name, "version": "1", "description": name, "parameters": ParameterSet(),
                                     "run": lambda self, inputs, params, context: {}})


@hookimpl
def mirrorlab_register_algorithms():
    return [_algorithm("lazy_declared"), _algorithm("lazy_undeclared")]


@hookimpl
def mirrorlab_add_cli_commands(subparsers):
    subparsers.add_parser("lazy_command", help="a command it does not declare")
'''


@pytest.fixture(scope="module")
def lazy_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A third-party plugin that declares one of its two algorithms in the group mirrorlab.provides."""
    src = tmp_path_factory.mktemp("lazy-src")
    (src / "lazy_mirrorlab").mkdir()
    (src / "lazy_mirrorlab" / "__init__.py").write_text(LAZY_PLUGIN)
    (src / "pyproject.toml").write_text(
        '[build-system]\nrequires = ["setuptools>=61"]\nbuild-backend = "setuptools.build_meta"\n'
        '[project]\nname = "mirrorlab-lazy"\nversion = "1.0.0"\n'
        '[project.entry-points.mirrorlab]\nlazy = "lazy_mirrorlab"\n'
        '[project.entry-points."mirrorlab.provides"]\n"algorithm.lazy_declared" = "lazy_mirrorlab"\n'
        '[tool.setuptools]\npackages = ["lazy_mirrorlab"]\n')
    return pip_install_target(src, tmp_path_factory.mktemp("lazy-site"))


def test_a_declared_plugin_is_imported_only_when_a_name_it_declares_is_asked_for(lazy_site: Path, with_sites) -> None:
    reg = with_sites(lazy_site)
    assert "lazy_mirrorlab" not in sys.modules and not reg.installed()["lazy"].loaded
    assert "lazy_declared" in reg.names("algorithm")  # known from the declaration alone
    assert "lazy_mirrorlab" not in sys.modules
    assert reg.algorithm("lazy_declared").name == "lazy_declared" and reg.installed()["lazy"].loaded
    assert reg.algorithm("lazy_undeclared").name == "lazy_undeclared"  # found once imported
    assert reg.undeclared() == ["plugin 'lazy' provides algorithm lazy_undeclared without declaring it in "
                                "entry-point group 'mirrorlab.provides'",
                                "plugin 'lazy' provides command lazy_command without declaring it in "
                                "entry-point group 'mirrorlab.provides'"]
    sys.modules.pop("lazy_mirrorlab")


def test_an_undeclared_name_is_still_found_and_doctor_says_what_to_declare(lazy_site: Path, with_sites) -> None:
    reg = with_sites(lazy_site)
    assert reg.algorithm("lazy_undeclared").name == "lazy_undeclared"  # not declared: every plugin is searched
    sys.modules.pop("lazy_mirrorlab")
    doctor = run_cli("plugins", "doctor", sites=(lazy_site,))
    assert doctor.returncode == 1
    assert "lazy [PROBLEM]" in doctor.stdout
    assert "problem: plugin 'lazy' provides algorithm lazy_undeclared without declaring it" in doctor.stdout
