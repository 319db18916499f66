"""Each built-in instrument and algorithm plugin is its own entry point: one whose import breaks leaves
every other plugin listed and working (in a fresh interpreter whose import system refuses the package).

A plugin that itself imports the refused package breaks with it, and only such a plugin: which
those are is measured, not listed here (each plugin imported and registered alone, in a fresh
interpreter), so the test states exactly "the blocked plugin and its importers break, all others
work".
"""

from __future__ import annotations

import importlib.metadata as md
import json
import subprocess
import sys
import textwrap

import pytest

from tests.support import REPO

#: The built-in entry points of instruments and algorithm plugins: (entry-point name, module).
PLUGINS = sorted((ep.name, ep.value) for ep in md.entry_points(group="mirrorlab")
                 if ep.dist is not None and ep.dist.name == "mirrorlab"
                 and ep.value.startswith(("mirrorlab.instruments.", "mirrorlab.plugins.")))

BLOCKED_RUN = textwrap.dedent('''
    import importlib.abc, json, sys

    blocked = sys.argv[1]

    class Refuse(importlib.abc.MetaPathFinder):
        """A broken package: every import of it or of its modules fails."""

        def find_spec(self, name, path=None, target=None):
            if name == blocked or name.startswith(blocked + "."):
                raise ImportError(f"{name} is blocked for this test")
            return None

    sys.meta_path.insert(0, Refuse())
    from mirrorlab.core.registry import Registry

    reg = Registry(entry_points=False)
    print(json.dumps({name: {"error": info.error, "provides": info.provides, "declared": info.declared}
                      for name, info in reg.plugins.items()}))
''')

DEPENDENCIES = textwrap.dedent('''
    import importlib, json, sys
    from mirrorlab.core.registry import Registry

    plugins = json.loads(sys.argv[1])  # entry-point name -> module
    packages = {name: module.rpartition(".")[0] for name, module in plugins.items()}

    def builtin_modules():
        return [m for m in sys.modules if m.startswith(("mirrorlab.instruments.", "mirrorlab.plugins."))]

    imports = {}
    for name, module in plugins.items():
        for loaded in builtin_modules():  # as in a fresh interpreter, as far as the built-in packages go
            del sys.modules[loaded]
        info = Registry(entry_points=False, builtins=False).add_plugin(importlib.import_module(module), name)
        assert info.ok, info.error
        loaded = builtin_modules()
        imports[name] = sorted(other for other, package in packages.items()
                               if any(m == package or m.startswith(package + ".") for m in loaded))
    print(json.dumps(imports))
''')


def _run(script: str, *args: str) -> dict:
    proc = subprocess.run([sys.executable, "-c", script, *args], capture_output=True, text=True, cwd=REPO, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout)


@pytest.fixture(scope="module")
def importers() -> dict[str, set[str]]:
    """Entry-point name -> the built-in plugins whose import and registration import its package."""
    imports = _run(DEPENDENCIES, json.dumps(dict(PLUGINS)))
    return {name: {other for other, packages in imports.items() if name in packages} for name, _ in PLUGINS}


def test_every_instrument_and_plugin_package_is_its_own_entry_point() -> None:
    packages = {module.rpartition(".")[0] for _, module in PLUGINS}
    on_disk = {f"mirrorlab.{path.parent.parent.name}.{path.parent.name}"
               for folder in ("instruments", "plugins") for path in (REPO / folder).glob("*/plugin.py")}
    assert packages == on_disk and len(PLUGINS) == len(packages)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "module"), PLUGINS, ids=[name for name, _ in PLUGINS])
def test_one_broken_import_leaves_every_other_plugin_listed(name: str, module: str,
                                                            importers: dict[str, set[str]]) -> None:
    package = module.rpartition(".")[0]
    listed = _run(BLOCKED_RUN, package)
    assert set(listed) == {n for n, _ in PLUGINS} | {"mirrorlab.core.steps"}
    broken = {n for n, info in listed.items() if info["error"]}
    assert broken == {name} | importers[name], {n: listed[n]["error"] for n in broken}
    for other in broken:
        assert package in listed[other]["error"] and "is blocked for this test" in listed[other]["error"]
    for other, info in listed.items():  # the others work whole: everything they declare is registered
        if other not in broken:
            declared = {kind: sorted(names) for kind, names in info["declared"].items() if kind not in ("hook", "command")}
            assert {kind: sorted(names) for kind, names in info["provides"].items()} == declared, other
