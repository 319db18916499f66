"""Plugin discovery and the registry of instruments, algorithms, controllers and recipe steps.

:func:`get_registry` builds (once per process) a pluggy ``PluginManager`` for the project
``mirrorlab`` and registers every entry point of the group ``mirrorlab``: the built-in plugins are
entry points of the ``mirrorlab`` distribution itself (``pyproject.toml``), third-party ones of
their own distributions; one route for both. It then calls the registration hooks through pluggy
(only functions marked with ``hookimpl`` count; ``tryfirst`` / ``trylast`` order the providers and
hook wrappers wrap every plugin's registration) and records which plugin returned which class.

A plugin that fails to import, fails hook validation, raises in a registration hook or returns a
class of the wrong kind (an algorithm from ``mirrorlab_register_instruments``) is recorded in
:attr:`Registry.broken` with a one-line error and its traceback; everything else keeps working.
Two providers of one name make that name *ambiguous*: asking for it raises
:class:`~mirrorlab.core.errors.DuplicateNameError` naming both, and ``mirrorlab plugins doctor``
lists the conflict.
"""

from __future__ import annotations

import importlib
import importlib.metadata as md
import traceback
from dataclasses import dataclass, field
from typing import Any

import pluggy

from . import hookspecs
from .errors import DuplicateNameError, PluginError

ENTRY_POINT_GROUP = "mirrorlab"
#: The distribution whose entry points are the built-in plugins.
BUILTIN_DISTRIBUTION = "mirrorlab"
KINDS = ("instrument", "algorithm", "controller", "step")
#: Registration hook of each kind.
HOOKS = {"instrument": "mirrorlab_register_instruments", "algorithm": "mirrorlab_register_algorithms",
         "controller": "mirrorlab_register_controllers", "step": "mirrorlab_register_steps"}
#: Base class each kind must subclass: kind -> (module, class name), imported when first checked.
BASES = {"instrument": ("mirrorlab.core.devices", "Instrument"), "algorithm": ("mirrorlab.core.algorithms", "Algorithm"),
         "controller": ("mirrorlab.core.controllers", "Controller"), "step": ("mirrorlab.core.steps", "Step")}
_REQUIRED = ("name", "version", "description", "parameters")


@dataclass
class PluginInfo:
    """A plugin as discovered: where it came from and whether it loaded."""

    name: str
    source: str  # the entry point "name = module:attr", or where an added plugin came from
    distribution: str = ""
    version: str = ""
    error: str = ""
    traceback: str = ""
    provides: dict[str, list[str]] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.error


@dataclass
class Provided:
    """One registered class and the plugin that provided it."""

    kind: str
    name: str
    cls: type
    plugin: str


class Registry:
    """Everything the installed plugins provide."""

    def __init__(self, entry_points: bool = True, builtins: bool = True) -> None:
        """Discover the entry points of group ``mirrorlab``.

        ``builtins=False`` skips those of the ``mirrorlab`` distribution (the built-in plugins),
        ``entry_points=False`` those of every other distribution (third-party plugins); with both
        off the registry is empty until :meth:`add_plugin`.
        """
        self.pm = pluggy.PluginManager(hookspecs.PROJECT)
        self.pm.add_hookspecs(hookspecs)
        self.plugins: dict[str, PluginInfo] = {}
        self._items: dict[str, dict[str, list[Provided]]] = {k: {} for k in KINDS}
        for ep in md.entry_points(group=ENTRY_POINT_GROUP):
            dist = ep.dist.name if ep.dist else ""
            if (builtins if dist == BUILTIN_DISTRIBUTION else entry_points):
                self._load(ep.name, f"{ep.name} = {ep.value}", ep.load, dist, ep.dist.version if ep.dist else "")
        self._collect([name for name, info in self.plugins.items() if info.ok])

    # -- loading -----------------------------------------------------------------------------------
    def _load(self, name: str, source: str, loader: Any, dist: str = "", version: str = "") -> None:
        info = PluginInfo(name, source, dist, version)
        self.plugins[name] = info
        try:
            plugin = loader()
            self.pm.register(plugin, name=name)
            self.pm.check_pending()
        except Exception as exc:  # any failure: record it, keep the others working
            info.error = f"{type(exc).__name__}: {exc}"
            info.traceback = traceback.format_exc()
            if self.pm.has_plugin(name):
                self.pm.unregister(name=name)

    def _collect(self, names: list[str]) -> None:
        """Call the registration hooks of the plugins ``names``; each plugin counts whole or not at all."""
        found: dict[str, dict[str, list[type]]] = {}
        for name in names:
            info = self.plugins[name]
            try:
                found[name] = {kind: self._call(kind, name) for kind in KINDS}
            except PluginError as exc:
                info.error = str(exc)
                info.traceback = traceback.format_exc()
                self.pm.unregister(name=name)  # nothing of a broken plugin runs: no hooks, no wrappers
        for kind in KINDS:  # providers of one name in pluggy's call order (tryfirst first)
            for name in self._call_order(kind):
                for cls in found.get(name, {}).get(kind, ()):
                    self._items[kind].setdefault(cls.name, []).append(Provided(kind, cls.name, cls, name))
                    self.plugins[name].provides.setdefault(kind, []).append(cls.name)

    def _call_order(self, kind: str) -> list[str]:
        impls = getattr(self.pm.hook, HOOKS[kind]).get_hookimpls()
        return [i.plugin_name for i in reversed(impls) if not (i.hookwrapper or i.wrapper)]

    def _call(self, kind: str, name: str) -> list[type]:
        """The classes plugin ``name`` registers for ``kind``: its hook called through pluggy, wrappers included."""
        others = [self.pm.get_plugin(n) for n in self._call_order(kind) if n != name]
        if len(others) == len(self._call_order(kind)):
            return []  # no implementation of this hook in this plugin
        caller = self.pm.subset_hook_caller(HOOKS[kind], remove_plugins=others)
        try:
            classes = [cls for result in caller() for cls in (result or ())]
        except Exception as exc:
            raise PluginError(f"plugin {name!r}: {HOOKS[kind]} failed: {type(exc).__name__}: {exc}") from exc
        for cls in classes:
            self._check_declaration(kind, cls, name)
        return classes

    def add_plugin(self, plugin: object, name: str, source: str = "added at run time") -> PluginInfo:
        """Register one more plugin object (a module or an object with hook functions).

        For scripts, notebooks and benchmarks that define plugins inline; installed packages use the
        entry-point group instead. A failure is recorded like any broken plugin and returned.
        """
        if name in self.plugins:
            raise PluginError(f"a plugin named {name!r} is already registered ({self.plugins[name].source})")
        self._load(name, source, lambda: plugin)
        info = self.plugins[name]
        if info.ok:
            self._collect([name])
        return info

    @staticmethod
    def _check_declaration(kind: str, cls: Any, plugin: str) -> None:
        """One-line :class:`PluginError` naming the plugin unless ``cls`` is a complete declaration of ``kind``."""
        hook = HOOKS[kind]
        if not isinstance(cls, type):
            raise PluginError(f"plugin {plugin!r}: {hook} returned {cls!r}, which is not a class")
        module, base_name = BASES[kind]
        base = getattr(importlib.import_module(module), base_name)
        if not issubclass(cls, base):
            actual = next((k for k, (m, b) in BASES.items() if issubclass(cls, getattr(importlib.import_module(m), b))),
                          None)
            what = f"{_a(actual)} {actual}" if actual else f"not {_a(kind)} {kind}"
            raise PluginError(f"plugin {plugin!r}: {hook} returned {cls.__module__}.{cls.__qualname__}, which is {what}; "
                              f"{kind}s subclass {module}.{base_name}")
        missing = [a for a in _REQUIRED if not getattr(cls, a, None) and a != "parameters"]
        if missing:
            raise PluginError(f"plugin {plugin!r}: {kind} {cls.__qualname__} does not declare {', '.join(missing)}")
        from .params import ParameterSet

        if not isinstance(getattr(cls, "parameters", None), ParameterSet):
            raise PluginError(f"plugin {plugin!r}: {kind} {cls.name!r}: `parameters` must be a ParameterSet")

    # -- queries -------------------------------------------------------------------------------------
    def names(self, kind: str) -> list[str]:
        return sorted(self._items[kind])

    def providers(self, kind: str, name: str) -> list[Provided]:
        """Every registration of ``name`` (more than one means a conflict)."""
        return list(self._items[kind].get(name, ()))

    def get(self, kind: str, name: str) -> type:
        """The class registered as ``name``; raises :class:`PluginError` or :class:`DuplicateNameError`."""
        providers = self._items[kind].get(name)
        if not providers:
            known = ", ".join(self.names(kind)) or "none"
            broken = [p.name for p in self.plugins.values() if not p.ok]
            hint = f"; broken plugins: {', '.join(broken)} (see `mirrorlab plugins doctor`)" if broken else ""
            raise PluginError(f"no {kind} named {name!r}; installed: {known}{hint}")
        if len(providers) > 1:
            raise DuplicateNameError(self._conflict_message(kind, name, providers))
        return providers[0].cls

    def instrument(self, name: str) -> type:
        return self.get("instrument", name)

    def algorithm(self, name: str) -> type:
        return self.get("algorithm", name)

    def controller(self, name: str) -> type:
        return self.get("controller", name)

    def step(self, name: str) -> type:
        return self.get("step", name)

    def conflicts(self) -> list[str]:
        """One message per ambiguous name."""
        return [self._conflict_message(kind, name, providers)
                for kind in KINDS for name, providers in sorted(self._items[kind].items())
                if len(providers) > 1]

    def _conflict_message(self, kind: str, name: str, providers: list[Provided]) -> str:
        who = " and ".join(f"{p.plugin} ({self.plugins[p.plugin].source})" for p in providers)
        return (f"the {kind} name {name!r} is provided by both {who}; "
                "uninstall one of them or ask its author to rename it")

    def provider(self, kind: str, name: str) -> PluginInfo:
        return self.plugins[self._items[kind][name][0].plugin]

    @property
    def broken(self) -> list[PluginInfo]:
        return [p for p in self.plugins.values() if not p.ok]

    @property
    def hook(self) -> Any:
        return self.pm.hook

    def notify(self, hook_name: str, **kwargs: Any) -> list[str]:
        """Call a lifecycle hook on every plugin; failures are returned as messages, never raised."""
        errors = []
        for impl in getattr(self.pm.hook, hook_name).get_hookimpls():
            try:
                impl.function(**{k: v for k, v in kwargs.items() if k in impl.argnames})
            except Exception as exc:
                errors.append(f"plugin {impl.plugin_name!r} failed in {hook_name}: {type(exc).__name__}: {exc}")
        return errors


def _a(word: str) -> str:
    return "an" if word[0] in "aeiou" else "a"


_registry: Registry | None = None


def get_registry(refresh: bool = False) -> Registry:
    """The process-wide registry (built on first use; ``refresh=True`` rediscovers plugins)."""
    global _registry
    if _registry is None or refresh:
        _registry = Registry()
    return _registry
