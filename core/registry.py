"""Plugin discovery and the registry of instruments, algorithms, controllers, recipe steps and TUI screens.

:func:`get_registry` builds (once per process) a pluggy ``PluginManager`` for the project
``mirrorlab`` and registers every entry point of the group ``mirrorlab``: the built-in plugins are
entry points of the ``mirrorlab`` distribution itself (``pyproject.toml``), third-party ones of
their own distributions; one route for both. It then calls the registration hooks through pluggy
(only functions marked with ``hookimpl`` count; ``tryfirst`` / ``trylast`` order the providers and
hook wrappers wrap every plugin's registration) and records which plugin returned what.

Every other hook (the session's lifecycle notifications, ``mirrorlab_add_cli_commands``) is called
through pluggy too, by :meth:`Registry.notify`: one plugin at a time in pluggy's order (``tryfirst``
first, ``trylast`` last, otherwise the plugin registered last first), each call wrapped by every hook
wrapper, so that a plugin that raises is reported and the others still run.

**Lazy loading.** A plugin may declare, as entry points of the group ``mirrorlab.provides``, every
name it registers, every lifecycle hook it implements and every CLI command it adds
(``"algorithm.derivatives" = "<its entry point's module>"``, ``"screen.chain" = ...``,
``"hook.mirrorlab_recording_stopped" = ...``, ``"command.kinematics" = ...``). Such a plugin is
imported only when one of its names, hooks or commands is asked for, so a command pays only for
the plugins it runs (the built-in plugins all declare theirs; ``tests/core/cli/test_cli_startup.py``
checks that the declarations match). The one-line help of a declared command is an entry point of
the group ``mirrorlab.commands`` (``kinematics = "<light module>:<attribute holding the help>"``), so
``mirrorlab --help`` lists it without importing the plugin. A plugin without declarations is
imported when the registry is built. Listing plugins (:attr:`Registry.plugins`,
:attr:`~Registry.broken`, :meth:`~Registry.conflicts`) imports every plugin.

A plugin that fails to import, fails hook validation, raises in a registration hook or returns a
declaration of the wrong kind (an algorithm from ``mirrorlab_register_instruments``) is recorded in
:attr:`Registry.broken` with a one-line error and its traceback; everything else keeps working.
Two providers of one name make that name *ambiguous*: asking for it raises
:class:`~mirrorlab.core.errors.DuplicateNameError` naming both, and ``mirrorlab plugins doctor``
lists the conflict.
"""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata as md
import threading
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal, cast, overload

import pluggy

from . import hookspecs
from .errors import DuplicateNameError, PluginError

if TYPE_CHECKING:
    from .algorithms import Algorithm
    from .controllers import Controller
    from .devices import Instrument
    from .steps import Step
    from .tui.screens import ScreenEntry

ENTRY_POINT_GROUP = "mirrorlab"
#: Entry-point group in which a plugin declares what it provides: ``"<kind>.<name>" = "<its module>"``,
#: kind one of :data:`REGISTERED`; ``"hook.<hook name>[.<tag>]"`` for a lifecycle hook it implements
#: (the optional tag keeps entry names unique when two plugins of a distribution implement one hook);
#: ``"command.<name>"`` for a CLI command it adds through ``mirrorlab_add_cli_commands``.
PROVIDES_GROUP = "mirrorlab.provides"
#: Entry-point group of the one-line help of declared CLI commands: ``<command> = "<module>:<attribute>"``,
#: the attribute a string in a module light enough for ``mirrorlab --help`` to import.
COMMANDS_GROUP = "mirrorlab.commands"
#: The distribution whose entry points are the built-in plugins.
BUILTIN_DISTRIBUTION = "mirrorlab"
#: The kinds of registered classes: each subclasses its base in :data:`BASES` and declares ``name``,
#: ``version``, ``description`` and ``parameters`` (what ``mirrorlab plugins`` lists and shows).
KINDS = ("instrument", "algorithm", "controller", "step")
#: Everything a plugin registers by name: the classes of :data:`KINDS`, and the console's screens
#: (:class:`~mirrorlab.core.tui.screens.ScreenEntry` declarations, not classes).
REGISTERED = (*KINDS, "screen")
#: Registration hook of each kind.
HOOKS = {"instrument": "mirrorlab_register_instruments", "algorithm": "mirrorlab_register_algorithms",
         "controller": "mirrorlab_register_controllers", "step": "mirrorlab_register_steps",
         "screen": "mirrorlab_register_screens"}
#: What each kind's registrations must be: kind -> (module, class name), imported when first checked.
#: A class kind's classes subclass it; a screen is an instance of it.
BASES = {"instrument": ("mirrorlab.core.devices", "Instrument"), "algorithm": ("mirrorlab.core.algorithms", "Algorithm"),
         "controller": ("mirrorlab.core.controllers", "Controller"), "step": ("mirrorlab.core.steps", "Step"),
         "screen": ("mirrorlab.core.tui.screens", "ScreenEntry")}
#: The hook through which plugins add CLI commands (declared as ``command.<name>``).
CLI_HOOK = "mirrorlab_add_cli_commands"
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
    #: What the plugin declares in ``mirrorlab.provides`` (kind -> names; kind ``hook``: hook names,
    #: kind ``command``: CLI commands).
    declared: dict[str, list[str]] = field(default_factory=dict)
    #: Whether it has been imported (a plugin with declarations is imported when first needed).
    loaded: bool = False

    @property
    def ok(self) -> bool:
        return not self.error


@dataclass
class Provided:
    """One registration (a class; for a screen its :class:`ScreenEntry`) and the plugin that provided it."""

    kind: str
    name: str
    cls: Any
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
        self._found: dict[str, dict[str, list[Any]]] = {}  # plugin -> kind -> what it registered
        self._items: dict[str, dict[str, list[Provided]]] = {k: {} for k in REGISTERED}
        self._command_help: dict[str, md.EntryPoint] = {}  # declared command -> where its help is
        self._loading = threading.RLock()  # see _load
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
            if plugin is not None and (kind in REGISTERED or kind in ("hook", "command")) and item:
                self._plugins[plugin].declared.setdefault(kind, []).append(item)
        dists = {_dist(ep) for ep in wanted}
        for ep in md.entry_points(group=COMMANDS_GROUP):
            if _dist(ep) in dists:
                self._command_help.setdefault(ep.name, ep)
        self._load([name for name, info in self._plugins.items() if not info.declared])

    # -- loading -----------------------------------------------------------------------------------
    def _load(self, names: Iterable[str]) -> None:
        """Import the pending plugins ``names`` and collect what they register. One thread at a time: the
        console's workers and its screens may need a plugin at once, and two collections interleaved
        would list its names twice."""
        with self._loading:
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
                self._found[name] = {kind: self._call(kind, name) for kind in REGISTERED}
            except PluginError as exc:
                info.error = str(exc)
                info.traceback = traceback.format_exc()
                self.pm.unregister(name=name)  # nothing of a broken plugin runs: no hooks, no wrappers
        for kind in REGISTERED:  # providers of one name in pluggy's call order (tryfirst first)
            items: dict[str, list[Provided]] = {}
            for name in self._call_order(HOOKS[kind]):
                for cls in self._found.get(name, {}).get(kind, ()):
                    items.setdefault(cls.name, []).append(Provided(kind, cls.name, cls, name))
            self._items[kind] = items  # whole: a reader in another thread never sees it half built
        for name in names:
            found = self._found.get(name, {})
            self._plugins[name].provides = {kind: [c.name for c in found[kind]] for kind in REGISTERED if found.get(kind)}

    def load_all(self) -> None:
        """Import every plugin not imported yet (listing, diagnosis)."""
        self._load(list(self._pending))

    def _need(self, kind: str, name: str) -> None:
        """Import the pending plugins that declare ``name`` of ``kind``."""
        self._load([p for p in list(self._pending) if name in self._plugins[p].declared.get(kind, ())])

    def _call_order(self, hook: str) -> list[str]:
        """The plugins implementing ``hook`` (wrappers aside), in pluggy's call order: ``tryfirst`` ones
        first, ``trylast`` ones last, otherwise the plugin registered last first."""
        impls = getattr(self.pm.hook, hook).get_hookimpls()  # pluggy keeps them in reverse call order
        return [i.plugin_name for i in reversed(impls) if not (i.hookwrapper or i.wrapper)]

    def _caller(self, hook: str, plugin: str) -> Callable[..., Any] | None:
        """The hook ``hook`` of ``plugin`` alone, wrapped by every hook wrapper of the hook, or None if
        ``plugin`` does not implement it.

        The implementations are chosen one by one (``subset_hook_caller`` would drop a plugin's
        wrapper together with its implementation) and run by the manager's own executor, the one
        its hook callers use, so that pluggy's call loop, order and hook-call monitoring apply.
        """
        impls = getattr(self.pm.hook, hook).get_hookimpls()
        chosen = [i for i in impls if i.wrapper or i.hookwrapper or i.plugin_name == plugin]
        if len(chosen) == sum(i.wrapper or i.hookwrapper for i in impls):
            return None
        return lambda **kwargs: self.pm._hookexec(hook, chosen, kwargs, False)

    def _call(self, kind: str, name: str) -> list[Any]:
        """What plugin ``name`` registers for ``kind``: its hook called through pluggy, wrappers included."""
        caller = self._caller(HOOKS[kind], name)
        if caller is None:
            return []
        try:
            registered = [item for result in caller() for item in (result or ())]
        except Exception as exc:
            raise PluginError(f"plugin {name!r}: {HOOKS[kind]} failed: {type(exc).__name__}: {exc}") from exc
        for item in registered:
            self._check_declaration(kind, item, name)
        return registered

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
        if kind == "screen":  # a declaration (its class is imported when the screen opens), complete once built
            module, base_name = BASES[kind]
            if not isinstance(cls, getattr(importlib.import_module(module), base_name)):
                raise PluginError(f"plugin {plugin!r}: {hook} returned {cls!r}, which is not a {base_name}; "
                                  f"screens are declared as {module}.{base_name}(name, key, title, help, target)")
            return
        if not isinstance(cls, type):
            raise PluginError(f"plugin {plugin!r}: {hook} returned {cls!r}, which is not a class")
        module, base_name = BASES[kind]
        base = getattr(importlib.import_module(module), base_name)
        if not issubclass(cls, base):
            actual = next((k for k in KINDS if issubclass(cls, getattr(importlib.import_module(BASES[k][0]), BASES[k][1]))),
                          None)
            what = f"{_a(actual)} {actual}" if actual else f"not {_a(kind)} {kind}"
            raise PluginError(f"plugin {plugin!r}: {hook} returned {cls.__module__}.{cls.__qualname__}, which is {what}; "
                              f"{kind}s subclass {module}.{base_name}")
        missing = [a for a in _REQUIRED if not getattr(cls, a, None) and a != "parameters"]
        if missing:
            raise PluginError(f"plugin {plugin!r}: {kind} {cls.__qualname__} does not declare {', '.join(missing)}")
        from .params import ParameterSet

        if not isinstance(getattr(cls, "parameters", None), ParameterSet):
            raise PluginError(f"plugin {plugin!r}: {kind} {cast(Any, cls).name!r}: `parameters` must be a ParameterSet")
        if kind == "algorithm":
            from .algorithms import role_problem

            problem = role_problem(cls)
            if problem:
                raise PluginError(f"plugin {plugin!r}: {problem}")

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
    def get(self, kind: Literal["screen"], name: str) -> ScreenEntry: ...
    @overload
    def get(self, kind: str, name: str) -> Any: ...

    def get(self, kind: str, name: str) -> Any:
        """The class (for a screen, its :class:`ScreenEntry`) registered as ``name``; raises
        :class:`PluginError` or :class:`DuplicateNameError`."""
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
                for kind in REGISTERED for name, providers in sorted(self._items[kind].items())
                if len(providers) > 1]

    def _conflict_message(self, kind: str, name: str, providers: list[Provided]) -> str:
        who = " and ".join(f"{p.plugin} ({self._plugins[p.plugin].source})" for p in providers)
        return (f"the {kind} name {name!r} is provided by both {who}; "
                "uninstall one of them or ask its author to rename it")

    def provider(self, kind: str, name: str) -> PluginInfo:
        return self._plugins[self.providers(kind, name)[0].plugin]

    def undeclared(self) -> list[str]:
        """Where a plugin's ``mirrorlab.provides`` declarations and what it registers, implements and
        adds differ, and declared commands without help (imports every plugin)."""
        self.load_all()
        problems = []
        for info in self._plugins.values():
            if not info.declared or not info.ok:
                continue
            actual = {kind: sorted(names) for kind, names in info.provides.items()}
            hooks = [hook for hook in _LIFECYCLE if info.name in self._call_order(hook)]
            if hooks:
                actual["hook"] = hooks
            commands, failure = self._commands_added_by(info.name)
            if failure:
                problems.append(failure)
            elif commands:
                actual["command"] = commands
            problems += [f"plugin {info.name!r} declares command {name} but no help for it in {COMMANDS_GROUP!r}"
                         for name in info.declared.get("command", ()) if name not in self._command_help]
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

    def _commands_added_by(self, plugin: str) -> tuple[list[str], str]:
        """The CLI commands ``plugin`` adds (its hook run on a scratch parser), and why that failed (``""``: it did not)."""
        from .cli.commands import Subcommands

        sub = argparse.ArgumentParser(prog="mirrorlab").add_subparsers()
        failed = self.notify(CLI_HOOK, plugins=[plugin], subparsers=Subcommands(sub, None))
        return sorted(sub.choices), "; ".join(failed)

    @property
    def hook(self) -> Any:
        return self.pm.hook

    def first_result(self, hook_name: str, **kwargs: Any) -> Any:
        """Call a ``firstresult`` hook through pluggy, after importing the plugins that declare it:
        the first answer that is not ``None`` (``None`` if there is none). Errors propagate."""
        self._need("hook", hook_name)
        return getattr(self.pm.hook, hook_name)(**kwargs)

    def commands(self) -> dict[str, list[str]]:
        """Every CLI command a plugin declares (``command.<name>``), by name -> the plugins declaring it
        (imports nothing)."""
        declared: dict[str, list[str]] = {}
        for info in self._plugins.values():
            for name in info.declared.get("command", ()):
                declared.setdefault(name, []).append(info.name)
        return dict(sorted(declared.items()))

    def command_help(self, name: str) -> str:
        """The one-line help of the declared command ``name`` (group ``mirrorlab.commands``), imports only
        the light module that holds it; ``""`` if none is declared or it cannot be read."""
        ep = self._command_help.get(name)
        try:
            return str(ep.load()) if ep is not None else ""
        except Exception:  # a broken plugin's command is still listed; running it reports the plugin's error
            return ""

    def notify(self, hook_name: str, /, *, plugins: Iterable[str] | None = None, **kwargs: Any) -> list[str]:
        """Call the hook ``hook_name`` with ``kwargs`` on every plugin that implements it (or only on
        ``plugins``); failures are returned as one-line messages naming the plugin, never raised.

        The hook is called through pluggy one plugin at a time, in pluggy's order (``tryfirst`` first,
        ``trylast`` last, otherwise the plugin registered last first), each call wrapped by every hook
        wrapper of the hook (``wrapper=True`` or ``hookwrapper=True``); so a plugin that raises stops
        neither the others nor the caller. Every plugin that declares the hook (``hook.<name>``) is
        imported first; ``plugins`` are imported if they are not yet.
        """
        if plugins is None:
            self._need("hook", hook_name)
        else:
            plugins = set(plugins)
            self._load(plugins)
        errors = []
        for name in self._call_order(hook_name):
            caller = self._caller(hook_name, name) if plugins is None or name in plugins else None
            if caller is None:
                continue
            try:
                caller(**kwargs)
            except Exception as exc:
                errors.append(f"plugin {name!r} failed in {hook_name}: {type(exc).__name__}: {exc}")
        return errors


#: The hooks called by name (lifecycle ones with :meth:`Registry.notify`, ``mirrorlab_read_motion`` with
#: :meth:`Registry.first_result`), which a plugin declares as ``hook.<name>``.
_LIFECYCLE = ("mirrorlab_session_opened", "mirrorlab_recording_started", "mirrorlab_recording_stopped",
              "mirrorlab_result_written", "mirrorlab_session_closing", "mirrorlab_read_motion")


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
