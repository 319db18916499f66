"""Plugin discovery and the registry of instruments, algorithms, controllers and recipe steps.

:func:`get_registry` builds (once per process) a pluggy ``PluginManager`` for the project
``mirrorlab`` and registers every entry point of the group ``mirrorlab``: the built-in plugins are
entry points of the ``mirrorlab`` distribution itself (``pyproject.toml``), third-party ones of
their own distributions; one route for both. It then calls the registration hooks through pluggy
(only functions marked with ``hookimpl`` count; ``tryfirst`` / ``trylast`` order the providers and
hook wrappers wrap every plugin's registration) and records which plugin returned which class.

**Lazy loading.** A plugin may declare, as entry points of the group ``mirrorlab.provides``, every
name it registers and every lifecycle hook it implements (``"algorithm.derivatives" =
"<its entry point's module>"``, ``"hook.mirrorlab_recording_stopped" = ...``). Such a plugin is
imported only when one of its names or hooks is asked for, so a command pays only for the plugins
it runs (the built-in plugins all declare theirs; ``tests/core/test_plugins.py`` checks that the
declarations match). A plugin without declarations is imported when the registry is built.
Listing plugins (:attr:`Registry.plugins`, :attr:`~Registry.broken`, :meth:`~Registry.conflicts`)
imports every plugin.

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
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, overload

import pluggy

from . import hookspecs
from .errors import DuplicateNameError, PluginError

if TYPE_CHECKING:
    from .algorithms import Algorithm
    from .controllers import Controller
    from .devices import Instrument
    from .steps import Step

ENTRY_POINT_GROUP = "mirrorlab"
#: Entry-point group in which a plugin declares what it provides: ``"<kind>.<name>" = "<its module>"``,
#: kind one of :data:`KINDS`, or ``"hook.<hook name>[.<tag>]"`` for a lifecycle hook it implements
#: (the optional tag keeps entry names unique when two plugins of a distribution implement one hook).
PROVIDES_GROUP = "mirrorlab.provides"
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
    #: What the plugin declares in ``mirrorlab.provides`` (kind -> names; kind ``hook``: hook names).
    declared: dict[str, list[str]] = field(default_factory=dict)
    #: Whether it has been imported (a plugin with declarations is imported when first needed).
    loaded: bool = False

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
        off the registry is empty until :meth:`add_plugin`. Plugins that declare what they provide
        are imported when first needed, the others now.
        """
        self.pm = pluggy.PluginManager(hookspecs.PROJECT)
        self.pm.add_hookspecs(hookspecs)
        self._plugins: dict[str, PluginInfo] = {}
        self._pending: dict[str, md.EntryPoint] = {}  # declared plugins not imported yet
        self._found: dict[str, dict[str, list[type]]] = {}  # plugin -> kind -> classes it registered
        self._items: dict[str, dict[str, list[Provided]]] = {k: {} for k in KINDS}
        wanted = [ep for ep in md.entry_points(group=ENTRY_POINT_GROUP)
                  if (builtins if _dist(ep) == BUILTIN_DISTRIBUTION else entry_points)]
        by_module = {(_dist(ep), ep.value): ep.name for ep in wanted}
        for ep in wanted:
            self._plugins[ep.name] = PluginInfo(ep.name, f"{ep.name} = {ep.value}", _dist(ep),
                                                ep.dist.version if ep.dist else "")
            self._pending[ep.name] = ep
        for ep in md.entry_points(group=PROVIDES_GROUP):
            plugin = by_module.get((_dist(ep), ep.value))
            kind, _, item = ep.name.partition(".")
            if kind == "hook":  # hook.<hook name>[.<tag>]: the tag keeps entry names unique in a distribution
                item = item.partition(".")[0]
            if plugin is not None and (kind in KINDS or kind == "hook") and item:
                self._plugins[plugin].declared.setdefault(kind, []).append(item)
        self._load([name for name, info in self._plugins.items() if not info.declared])

    # -- loading -----------------------------------------------------------------------------------
    def _load(self, names: Iterable[str]) -> None:
        """Import the pending plugins ``names`` and collect what they register."""
        loaded = []
        for name in names:
            ep = self._pending.pop(name, None)
            if ep is not None:
                self._register(self._plugins[name], ep.load)
                loaded.append(name)
        self._collect([name for name in loaded if self._plugins[name].ok])

    def _register(self, info: PluginInfo, loader: Any) -> None:
        info.loaded = True
        try:
            plugin = loader()
            self.pm.register(plugin, name=info.name)
            self.pm.check_pending()
        except Exception as exc:  # any failure: record it, keep the others working
            info.error = f"{type(exc).__name__}: {exc}"
            info.traceback = traceback.format_exc()
            if self.pm.has_plugin(info.name):
                self.pm.unregister(name=info.name)

    def _collect(self, names: list[str]) -> None:
        """Call the registration hooks of the plugins ``names``; each plugin counts whole or not at all."""
        for name in names:
            info = self._plugins[name]
            try:
                self._found[name] = {kind: self._call(kind, name) for kind in KINDS}
            except PluginError as exc:
                info.error = str(exc)
                info.traceback = traceback.format_exc()
                self.pm.unregister(name=name)  # nothing of a broken plugin runs: no hooks, no wrappers
        for kind in KINDS:  # providers of one name in pluggy's call order (tryfirst first)
            self._items[kind] = {}
            for name in self._call_order(kind):
                for cls in self._found.get(name, {}).get(kind, ()):
                    self._items[kind].setdefault(cls.name, []).append(Provided(kind, cls.name, cls, name))
        for name in names:
            found = self._found.get(name, {})
            self._plugins[name].provides = {kind: [c.name for c in found[kind]] for kind in KINDS if found.get(kind)}

    def load_all(self) -> None:
        """Import every plugin not imported yet (listing, diagnosis)."""
        self._load(list(self._pending))

    def _need(self, kind: str, name: str) -> None:
        """Import the pending plugins that declare ``name`` of ``kind``."""
        self._load([p for p in list(self._pending) if name in self._plugins[p].declared.get(kind, ())])

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
        if name in self._plugins:
            raise PluginError(f"a plugin named {name!r} is already registered ({self._plugins[name].source})")
        info = self._plugins[name] = PluginInfo(name, source)
        self._register(info, lambda: plugin)
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
    @property
    def plugins(self) -> dict[str, PluginInfo]:
        """Every plugin, by name (imports those not imported yet)."""
        self.load_all()
        return dict(self._plugins)

    def installed(self) -> dict[str, PluginInfo]:
        """Every plugin, by name, as known now: imported or only declared (imports nothing)."""
        return dict(self._plugins)

    def names(self, kind: str) -> list[str]:
        """Every name of ``kind``: registered by an imported plugin or declared by another (imports nothing)."""
        declared = {n for p in self._pending for n in self._plugins[p].declared.get(kind, ())}
        return sorted(declared.union(self._items[kind]))

    def providers(self, kind: str, name: str) -> list[Provided]:
        """Every registration of ``name`` (more than one means a conflict)."""
        self._need(kind, name)
        return list(self._items[kind].get(name, ()))

    @overload
    def get(self, kind: Literal["instrument"], name: str) -> type[Instrument]: ...
    @overload
    def get(self, kind: Literal["algorithm"], name: str) -> type[Algorithm]: ...
    @overload
    def get(self, kind: Literal["controller"], name: str) -> type[Controller]: ...
    @overload
    def get(self, kind: Literal["step"], name: str) -> type[Step]: ...
    @overload
    def get(self, kind: str, name: str) -> type: ...

    def get(self, kind: str, name: str) -> type:
        """The class registered as ``name``; raises :class:`PluginError` or :class:`DuplicateNameError`."""
        providers = self.providers(kind, name)
        if not providers:
            self.load_all()  # a declaration that does not hold, or a name no one provides: look everywhere
            providers = self._items[kind].get(name, [])
        if not providers:
            known = ", ".join(self.names(kind)) or "none"
            broken = [p.name for p in self._plugins.values() if not p.ok]
            hint = f"; broken plugins: {', '.join(broken)} (see `mirrorlab plugins doctor`)" if broken else ""
            raise PluginError(f"no {kind} named {name!r}; installed: {known}{hint}")
        if len(providers) > 1:
            raise DuplicateNameError(self._conflict_message(kind, name, providers))
        return providers[0].cls

    def instrument(self, name: str) -> type[Instrument]:
        return self.get("instrument", name)

    def algorithm(self, name: str) -> type[Algorithm]:
        return self.get("algorithm", name)

    def controller(self, name: str) -> type[Controller]:
        return self.get("controller", name)

    def step(self, name: str) -> type[Step]:
        return self.get("step", name)

    def conflicts(self) -> list[str]:
        """One message per ambiguous name (imports every plugin)."""
        self.load_all()
        return [self._conflict_message(kind, name, providers)
                for kind in KINDS for name, providers in sorted(self._items[kind].items())
                if len(providers) > 1]

    def _conflict_message(self, kind: str, name: str, providers: list[Provided]) -> str:
        who = " and ".join(f"{p.plugin} ({self._plugins[p.plugin].source})" for p in providers)
        return (f"the {kind} name {name!r} is provided by both {who}; "
                "uninstall one of them or ask its author to rename it")

    def provider(self, kind: str, name: str) -> PluginInfo:
        return self._plugins[self.providers(kind, name)[0].plugin]

    def undeclared(self) -> list[str]:
        """Where a plugin's ``mirrorlab.provides`` declarations and its registrations differ (imports every plugin)."""
        self.load_all()
        problems = []
        for info in self._plugins.values():
            if not info.declared or not info.ok:
                continue
            actual = {kind: sorted(names) for kind, names in info.provides.items()}
            hooks = [hook for hook in _LIFECYCLE
                     if any(i.plugin_name == info.name for i in getattr(self.pm.hook, hook).get_hookimpls())]
            if hooks:
                actual["hook"] = hooks
            declared = {kind: sorted(names) for kind, names in info.declared.items()}
            for kind in sorted(set(actual) | set(declared)):
                missing = sorted(set(actual.get(kind, ())) - set(declared.get(kind, ())))
                extra = sorted(set(declared.get(kind, ())) - set(actual.get(kind, ())))
                if missing:
                    problems.append(f"plugin {info.name!r} provides {kind} {', '.join(missing)} without declaring it "
                                    f"in entry-point group {PROVIDES_GROUP!r}")
                if extra:
                    problems.append(f"plugin {info.name!r} declares {kind} {', '.join(extra)} in {PROVIDES_GROUP!r} "
                                    "but does not provide it")
        return problems

    @property
    def broken(self) -> list[PluginInfo]:
        """Plugins that failed to load or register (imports every plugin)."""
        return [p for p in self.plugins.values() if not p.ok]

    @property
    def hook(self) -> Any:
        return self.pm.hook

    def first_result(self, hook_name: str, **kwargs: Any) -> Any:
        """Call a ``firstresult`` hook through pluggy, after importing the plugins that declare it:
        the first answer that is not ``None`` (``None`` if there is none). Errors propagate."""
        self._need("hook", hook_name)
        return getattr(self.pm.hook, hook_name)(**kwargs)

    def notify(self, hook_name: str, **kwargs: Any) -> list[str]:
        """Call a lifecycle hook on every plugin; failures are returned as messages, never raised."""
        self._need("hook", hook_name)
        errors = []
        for impl in getattr(self.pm.hook, hook_name).get_hookimpls():
            try:
                impl.function(**{k: v for k, v in kwargs.items() if k in impl.argnames})
            except Exception as exc:
                errors.append(f"plugin {impl.plugin_name!r} failed in {hook_name}: {type(exc).__name__}: {exc}")
        return errors


#: The hooks called by name (lifecycle ones with :meth:`Registry.notify`, ``mirrorlab_read_motion`` with
#: :meth:`Registry.first_result`), which a plugin declares as ``hook.<name>``.
_LIFECYCLE = ("mirrorlab_session_opened", "mirrorlab_recording_started", "mirrorlab_recording_stopped",
              "mirrorlab_result_written", "mirrorlab_session_closing", "mirrorlab_add_cli_commands",
              "mirrorlab_read_motion")


def _dist(ep: md.EntryPoint) -> str:
    return ep.dist.name if ep.dist else ""


def _a(word: str) -> str:
    return "an" if word[0] in "aeiou" else "a"


_registry: Registry | None = None


def get_registry(refresh: bool = False) -> Registry:
    """The process-wide registry (built on first use; ``refresh=True`` rediscovers plugins)."""
    global _registry
    if _registry is None or refresh:
        _registry = Registry()
    return _registry
