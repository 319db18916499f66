"""Plugin discovery and the registry of instruments, algorithms and recipe steps.

:func:`get_registry` builds (once per process) a pluggy ``PluginManager`` for the project
``mirrorlab``, registers the built-in plugins (``mirrorlab.instruments``, ``mirrorlab.plugins``,
the core's own steps) and every entry point of the group ``mirrorlab``, then collects what the
registration hooks return.

A plugin that fails to import, fails hook validation or raises in a registration hook is
recorded in :attr:`Registry.broken` with its error and traceback; everything else keeps working.
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
BUILTIN_PLUGINS = ("mirrorlab.core.steps", "mirrorlab.instruments")
#: Module whose ``builtin_plugins()`` lists further built-in plugins, each loaded on its own.
BUILTIN_ADAPTERS = "mirrorlab.plugins"
KINDS = ("instrument", "algorithm", "controller", "step")
_REQUIRED = ("name", "version", "description", "parameters")


@dataclass
class PluginInfo:
    """A plugin as discovered: where it came from and whether it loaded."""

    name: str
    source: str  # "builtin" or the entry point "name = module:attr"
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
        """Discover the built-in plugins (unless ``builtins=False``) and the entry points (unless ``entry_points=False``)."""
        self.pm = pluggy.PluginManager(hookspecs.PROJECT)
        self.pm.add_hookspecs(hookspecs)
        self.plugins: dict[str, PluginInfo] = {}
        self._items: dict[str, dict[str, list[Provided]]] = {k: {} for k in KINDS}
        if builtins:
            for module in BUILTIN_PLUGINS:
                self._load(module, "builtin", lambda m=module: importlib.import_module(m))
            for name, loader in importlib.import_module(BUILTIN_ADAPTERS).builtin_plugins():
                self._load(name, "builtin", loader)
        if entry_points:
            for ep in md.entry_points(group=ENTRY_POINT_GROUP):
                dist = ep.dist.name if ep.dist else ""
                version = ep.dist.version if ep.dist else ""
                self._load(ep.name, f"{ep.name} = {ep.value}", ep.load, dist, version)
        self._collect()

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

    def _collect(self) -> None:
        for plugin_name, info in self.plugins.items():
            if info.ok:
                self._collect_plugin(plugin_name, info)

    def _collect_plugin(self, plugin_name: str, info: PluginInfo) -> None:
        """Call the registration hooks of one plugin; all its classes count, or none of them."""
        hooks = {"instrument": "mirrorlab_register_instruments",
                 "algorithm": "mirrorlab_register_algorithms",
                 "controller": "mirrorlab_register_controllers",
                 "step": "mirrorlab_register_steps"}
        plugin = self.pm.get_plugin(plugin_name)
        found: list[tuple[str, type]] = []
        for kind, hook_name in hooks.items():
            impl = getattr(plugin, hook_name, None)
            if impl is None:
                continue
            try:
                classes = list(impl() or [])
                for cls in classes:
                    self._check_declaration(kind, cls)
            except Exception as exc:
                info.error = f"{hook_name} failed: {type(exc).__name__}: {exc}"
                info.traceback = traceback.format_exc()
                return
            found += [(kind, cls) for cls in classes]
        for kind, cls in found:
            self._items[kind].setdefault(cls.name, []).append(Provided(kind, cls.name, cls, plugin_name))
            info.provides.setdefault(kind, []).append(cls.name)

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
            self._collect_plugin(name, info)
        return info

    @staticmethod
    def _check_declaration(kind: str, cls: Any) -> None:
        missing = [a for a in _REQUIRED if not getattr(cls, a, None) and a != "parameters"]
        if missing or not isinstance(cls, type):
            raise PluginError(f"{kind} {cls!r} does not declare {', '.join(missing) or 'a class'}")
        from .params import ParameterSet

        if not isinstance(getattr(cls, "parameters", None), ParameterSet):
            raise PluginError(f"{kind} {cls.name!r}: `parameters` must be a ParameterSet")

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


_registry: Registry | None = None


def get_registry(refresh: bool = False) -> Registry:
    """The process-wide registry (built on first use; ``refresh=True`` rediscovers plugins)."""
    global _registry
    if _registry is None or refresh:
        _registry = Registry()
    return _registry
