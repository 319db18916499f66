"""Lazy start-up: `--version` and `--help` import no plugin and no heavy library; commands still work.

The timings themselves live in ``benchmarks/bench_cli_startup.py`` (no timed unit tests); here we
check the cause of slowness, what is imported, in a fresh interpreter.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from tests.support import REPO, plugin_site, run_cli

#: Modules (and their sub-modules) that must not be imported to print the version or the top-level
#: help: heavy libraries, any plugin sub-package or instrument, the session machinery. The light
#: ``mirrorlab.plugins`` package itself is read for its commands' help (entry-point group mirrorlab.commands).
HEAVY = ("numpy", "scipy", "h5py", "cv2", "matplotlib", "rich", "mirrorlab.plugins.", "mirrorlab.instruments",
         "mirrorlab.core.session", "mirrorlab.core.algorithms")

PROBE = textwrap.dedent("""
    import json, sys
    from mirrorlab.core.cli import main
    try:
        code = main(sys.argv[1:])
    except SystemExit as exc:
        code = exc.code
    print("MODULES " + json.dumps(sorted(sys.modules)))
    sys.exit(code)
""")


def _imported(*args: str) -> tuple[int, str, set[str]]:
    proc = subprocess.run([sys.executable, "-c", PROBE, *args], capture_output=True, text=True, cwd=REPO, timeout=60)
    head, _, modules = proc.stdout.rpartition("MODULES ")
    return proc.returncode, head, set(json.loads(modules))


@pytest.mark.parametrize("args", [("--version",), ("--help",), ()])
def test_version_and_help_import_nothing_heavy(args: tuple[str, ...]) -> None:
    code, out, modules = _imported(*args)
    assert code == (2 if not args else 0)
    heavy = sorted(m for m in modules if any(m == h or m.startswith(h if h.endswith(".") else h + ".") for h in HEAVY))
    assert not heavy, heavy
    if args != ("--version",):
        for name in ("calibrate", "reconstruct", "kinematics", "session", "run", "demo", "analyze", "record"):
            assert re.search(rf"^ +{name}( |$)", out, re.M), (name, out)


def test_one_command_imports_only_its_own_plugin() -> None:
    code, out, modules = _imported("kinematics", "--help")
    assert code == 0 and "import" in out and "derivatives" in out
    assert "mirrorlab.plugins.kinematics.cli" in modules
    assert not any(m.startswith(("mirrorlab.plugins.photogrammetry", "mirrorlab.plugins.markers")) for m in modules)


def test_light_table_matches_the_real_parsers() -> None:
    """Every built-in command's light entry (name, help) is what its parser declares."""
    from mirrorlab.core.cli import build_parser, commands
    from mirrorlab.core.registry import Registry

    full = build_parser()
    sub = next(a for a in full._actions if a.dest == "command")
    real = {a.dest: a.help for a in sub._choices_actions}
    light = commands.command_table(Registry(entry_points=False))
    assert real == light


PLUGIN = '''
import sys

from mirrorlab.core import hookimpl


def _hello(args):
    print(f"hello {args.name}")
    return 0


@hookimpl
def mirrorlab_add_cli_commands(subparsers):
    p = subparsers.add_parser("hello", help="say hello (a third-party command)")
    p.add_argument("--name", default="world")
    p.set_defaults(func=_hello)


@hookimpl(wrapper=True, specname="mirrorlab_add_cli_commands")
def watch_commands(subparsers):
    """A hook wrapper: it wraps every plugin's commands, the built-in ones too."""
    had = "kinematics" in subparsers
    result = yield
    if not had and "kinematics" in subparsers:
        print(f"wrapped: kinematics added for {subparsers.argv}", file=sys.stderr)
    return result
'''


@pytest.fixture(scope="module")
def hello_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return plugin_site(PLUGIN, "mirrorlab-hello", "hello", tmp_path_factory.mktemp("hello-src"),
                       tmp_path_factory.mktemp("hello-site"))


def test_third_party_commands_still_work(hello_site: Path) -> None:
    ran = run_cli("hello", "--name", "lab", sites=(hello_site,))
    assert ran.returncode == 0 and ran.stdout == "hello lab\n", ran.stderr
    listed = run_cli("--help", sites=(hello_site,))
    assert listed.returncode == 0 and "say hello (a third-party command)" in listed.stdout
    assert re.search(r"^ +calibrate( |$)", listed.stdout, re.M)
    unknown = run_cli("helo", sites=(hello_site,))
    assert unknown.returncode == 2 and "invalid choice: 'helo'" in unknown.stderr
    assert "hello" in unknown.stderr and "calibrate" in unknown.stderr
    builtin = run_cli("plugins", sites=(hello_site,))
    assert builtin.returncode == 0 and "filter" in builtin.stdout


def test_builtin_commands_are_added_through_the_hook(hello_site: Path) -> None:
    """One route: the kinematics command is added by its plugin's mirrorlab_add_cli_commands, which a
    third-party hook wrapper sees; the top-level help lists it without importing the plugin."""
    ran = run_cli("kinematics", "--help", sites=(hello_site,))
    assert ran.returncode == 0 and "derivatives" in ran.stdout
    assert ran.stderr == "wrapped: kinematics added for ['kinematics', '--help']\n"
    listed = run_cli("--help", sites=(hello_site,))
    assert re.search(r"^ +kinematics\n +marker import/export", listed.stdout, re.M) and "wrapped" not in listed.stderr


def _plugin_packages(modules: set[str]) -> set[str]:
    """The built-in plugin packages among ``modules`` (``plugins.kinematics``, ``instruments.film_scanner``)."""
    return {".".join(m.split(".")[1:3]) for m in modules
            if m.startswith(("mirrorlab.plugins.", "mirrorlab.instruments.")) and m.count(".") >= 2}


def test_commands_import_only_the_plugins_they_run(tmp_path: Path) -> None:
    """The registry imports a plugin only for a name it declares (entry-point group mirrorlab.provides)."""
    trc = tmp_path / "walk.trc"
    rows = "".join(f"{i + 1}\t{i / 100:.2f}\t{i:.1f}\t0.0\t0.0\n" for i in range(20))
    trc.write_text("PathFileType\t4\t(X/Y/Z)\twalk.trc\nDataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\t"
                   "OrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n100\t100\t20\t1\tmm\t100\t1\t20\n"
                   "Frame#\tTime\tM\t\t\n\t\tX1\tY1\tZ1\n\n" + rows)
    session = tmp_path / "s.h5"
    code, _, modules = _imported("kinematics", "import", str(trc), "--session", str(session))
    assert code == 0 and _plugin_packages(modules) == {"plugins.kinematics"}, sorted(_plugin_packages(modules))
    for command in (("session", "info"), ("session", "tree"), ("session", "check")):
        code, out, modules = _imported(*command, str(session))
        assert code == 0 and _plugin_packages(modules) == set(), (command, sorted(_plugin_packages(modules)))
    run = "/markers/walk"
    code, out, modules = _imported("analyze", "derivatives", str(session), "--no-progress",
                                   "--input", f"time={run}/time", "--input", f"values={run}/points")
    assert code == 0 and _plugin_packages(modules) == {"plugins.kinematics"}, (out, sorted(_plugin_packages(modules)))


def test_declarations_match_what_the_builtin_plugins_register() -> None:
    """What pyproject.toml declares under mirrorlab.provides is what each built-in plugin registers."""
    from mirrorlab.core.registry import Registry

    reg = Registry(entry_points=False)
    assert reg.undeclared() == []
    assert all(info.declared for info in reg.installed().values()), "every built-in plugin declares what it provides"


BLOCKED = textwrap.dedent("""
    import importlib.abc, sys

    class Refuse(importlib.abc.MetaPathFinder):
        def find_spec(self, name, path=None, target=None):
            if name.startswith("mirrorlab.plugins.kinematics"):
                raise ImportError(f"{name} is blocked for this test")

    sys.meta_path.insert(0, Refuse())
    from mirrorlab.core.cli import main
    sys.exit(main(sys.argv[1:]))
""")


def test_a_broken_plugins_command_is_listed_and_fails_naming_the_plugin() -> None:
    def run(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-c", BLOCKED, *args], capture_output=True, text=True, cwd=REPO,
                              timeout=120)

    listed = run("--help")
    assert listed.returncode == 0 and re.search(r"^ +kinematics\n +marker import/export", listed.stdout, re.M)
    ran = run("kinematics", "--help")
    assert ran.returncode == 1 and ran.stderr == (
        "mirrorlab: error: the command 'kinematics' is not available: plugin 'mirrorlab.plugins.kinematics' is broken: "
        "ImportError: mirrorlab.plugins.kinematics is blocked for this test (see `mirrorlab plugins doctor`)\n")
    assert run("session", "--help").returncode == 0  # the other commands are unaffected
