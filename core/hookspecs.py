"""Hook specifications of the ``mirrorlab`` pluggy project.

A plugin is any module or object with functions marked by :data:`hookimpl` (unmarked functions
are not hook implementations). Every plugin, built-in or third-party, is found through the
entry-point group ``mirrorlab``; the built-in ones are entry points of the ``mirrorlab``
distribution (``mirrorlab.core.steps``, each ``mirrorlab.instruments.<name>.plugin`` and
``mirrorlab.plugins.<name>.plugin``), each declaring what it provides in the group
``mirrorlab.provides`` so that it is imported only when used (see :mod:`mirrorlab.core.registry`)::

    # pyproject.toml of a third-party package
    [project.entry-points.mirrorlab]
    acme = "acme_mirrorlab.plugin"

    # acme_mirrorlab/plugin.py
    from mirrorlab.core import hookimpl

    @hookimpl
    def mirrorlab_register_instruments():
        return [AcmeThermometer]

Every hook is called through pluggy, by the :class:`~mirrorlab.core.registry.Registry`, one plugin
at a time and in pluggy's order: implementations marked ``tryfirst`` first, ``trylast`` last,
otherwise the plugin registered last first. A hook wrapper (``@hookimpl(wrapper=True)``, or the
old-style ``hookwrapper=True``) wraps each plugin's call and sees (and may change) its result or
exception. An implementation may take fewer parameters than the specification names (pluggy
passes only those it asks for). Every implementation runs, except for ``mirrorlab_read_motion``
(``firstresult``: the first answer that is not ``None`` is used, through pluggy's own call).

Registration hooks return what the plugin provides: classes (instruments, algorithms,
controllers, recipe steps) and screen declarations. The registry checks each (the base class of
its kind, name, version, description, typed parameters) and records which plugin provided it, so
that duplicates can be reported naming both providers; a plugin whose registration hook raises or
returns something of the wrong kind is *broken* (``mirrorlab plugins doctor``), and nothing of it
is used.

Lifecycle hooks are notifications: they are called in the thread that drives the session, must
return quickly and should not raise; an exception is reported as a ``plugin_error`` warning event
in the session log naming the plugin, and the session and the other plugins go on. Live data
never flows through hooks: subscribe to streams with :meth:`mirrorlab.core.Session.subscribe`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    from .algorithms import Algorithm, ResultRef
    from .cli.commands import Subcommands
    from .controllers import Controller
    from .devices import Instrument
    from .session import Session
    from .steps import Step
    from .tui.screens import ScreenEntry

PROJECT = "mirrorlab"

hookspec = pluggy.HookspecMarker(PROJECT)
#: Marker for hook implementations in plugins: ``@hookimpl def mirrorlab_register_instruments(): ...``
hookimpl = pluggy.HookimplMarker(PROJECT)


# -- registration ------------------------------------------------------------------------------
@hookspec
def mirrorlab_register_instruments() -> list[type[Instrument]]:
    """Return the instrument classes this plugin provides.

    Each class subclasses :class:`mirrorlab.core.devices.Instrument` and declares ``name``,
    ``version``, ``description`` and ``parameters``; a simulated device sets ``simulator`` (or
    overrides :meth:`~mirrorlab.core.devices.Instrument.make_simulator`).

    :returns: The classes, in any order. A class of another kind (an algorithm, say) makes the
        plugin broken, with a one-line error naming it.

    Called once per plugin and process, when the registry imports the plugin: as it is built for
    a plugin that declares nothing, else when one of the names the plugin declares
    (``instrument.<name>`` in ``mirrorlab.provides``) is first asked for.
    """


@hookspec
def mirrorlab_register_algorithms() -> list[type[Algorithm]]:
    """Return the algorithm classes this plugin provides.

    Each class subclasses :class:`mirrorlab.core.algorithms.Algorithm`: a pure function of its
    input arrays and typed parameters, runnable from the CLI, a recipe, the TUI or a script. One
    that declares ``roles`` (:data:`mirrorlab.core.algorithms.ROLES`) must have each role's ports.

    :returns: The classes, in any order.

    Called once per plugin and process, when the registry imports the plugin (see
    :func:`mirrorlab_register_instruments`).
    """


@hookspec
def mirrorlab_register_controllers() -> list[type[Controller]]:
    """Return the controller classes this plugin provides.

    Each class subclasses :class:`mirrorlab.core.controllers.Controller`: live logic (a closed
    loop, a set-point schedule) that subscribes to streams and commands instruments while the
    session acquires, with everything it did recorded under ``/controllers/<label>``.

    :returns: The classes, in any order.

    Called once per plugin and process, when the registry imports the plugin (see
    :func:`mirrorlab_register_instruments`).
    """


@hookspec
def mirrorlab_register_steps() -> list[type[Step]]:
    """Return the recipe step kinds (``[[steps]] action = "..."``) this plugin provides.

    Each class subclasses :class:`mirrorlab.core.steps.Step`, whose ``parameters`` validate the
    step's table in a recipe before anything runs.

    :returns: The classes, in any order.

    Called once per plugin and process, when the registry imports the plugin (see
    :func:`mirrorlab_register_instruments`).
    """


@hookspec
def mirrorlab_register_screens() -> list[ScreenEntry]:
    """Return the screens this plugin adds to the operator console (``mirrorlab tui``).

    Each is a :class:`mirrorlab.core.tui.ScreenEntry`: a name (declared as ``screen.<name>`` in
    ``mirrorlab.provides``), the dashboard key that opens it, its title and one help line for the
    command palette and the help, and the ``"module:Class"`` of its Textual screen, imported only
    when the operator opens it (so registering a screen imports no Textual).

    :returns: The declarations, in any order; the console lists the plugins' screens after its
        own, by name. A key the dashboard already uses is not bound (the console says so, and the
        palette still opens the screen).

    Called once per plugin and process, when the registry imports the plugin: the console asks
    for every screen when it starts (see :func:`mirrorlab_register_instruments`).
    """


# -- command line ------------------------------------------------------------------------------
@hookspec
def mirrorlab_add_cli_commands(subparsers: Subcommands) -> None:
    """Add sub-commands to the ``mirrorlab`` CLI.

    :param subparsers: The CLI's command table (:class:`mirrorlab.core.Subcommands`).
        ``subparsers.add_parser(name, help=...)`` adds a command and returns its
        ``argparse.ArgumentParser``; set its default ``func`` to a callable taking the parsed
        ``argparse.Namespace`` and returning an exit code (0 ok, 1 runtime failure, 2 usage or
        validation error). ``subparsers.argv`` is the command line being parsed (None: every
        parser is being built, for the full help). A name that is already a command raises
        ``ValueError``, reported as a warning naming the plugin.

    Called once per ``mirrorlab`` command line, only when needed: for a plugin that declares its
    commands (``command.<name>`` in ``mirrorlab.provides``, the help in ``mirrorlab.commands``),
    when the command line names one of them; for a plugin that declares none, for the top-level
    help and for a command no plugin declares. ``mirrorlab --help`` lists the declared commands
    without importing their plugins (see :mod:`mirrorlab.core.cli.commands`).
    """


# -- session lifecycle ---------------------------------------------------------------------------
@hookspec
def mirrorlab_session_opened(session: Session) -> None:
    """A session file was created or opened.

    :param session: The session; ``session.writable`` tells whether it was created or opened for
        writing (a recording or analysis) or opened read-only (browsing).

    Called once per :class:`~mirrorlab.core.Session` object, at the end of
    :meth:`~mirrorlab.core.Session.create` or :meth:`~mirrorlab.core.Session.open`, before any
    instrument is added.
    """


@hookspec
def mirrorlab_recording_started(session: Session) -> None:
    """Recording started.

    :param session: The session: every recorded instrument is acquiring and the file is in SWMR
        mode (no group or attribute may be created until recording stops).

    Called by :meth:`~mirrorlab.core.Session.start_recording` (and ``record``) once everything
    records, while the session's lock is held: return at once.
    """


@hookspec
def mirrorlab_recording_stopped(session: Session, statistics: dict[str, Any]) -> None:
    """Recording stopped and everything recorded is written.

    :param session: The session, writable again (SWMR ended; acquisition may go on as a preview).
    :param statistics: ``"<source>/<stream>"`` -> ``{"samples": written, "dropped": dropped}`` of
        this recording, every recorded stream of instruments and controllers.

    Called by :meth:`~mirrorlab.core.Session.stop_recording` (and ``record``) after the file has
    been flushed.
    """


@hookspec
def mirrorlab_result_written(session: Session, result: ResultRef) -> None:
    """An algorithm run finished and its result group was written.

    :param session: The session holding the result.
    :param result: Where the run is stored (``result.path``, ``/results/<algorithm>/run-NNNN``) and
        how it ended: ``result.status`` ``ok``, ``failed`` (with ``result.error``) or ``cancelled``.

    Called by :meth:`~mirrorlab.core.Session.run` (recipes' ``run`` steps, ``mirrorlab analyze``,
    the console's analysis screen) after the result group is flushed, once per run.
    """


@hookspec
def mirrorlab_session_closing(session: Session, status: str) -> None:
    """A writable session is about to close.

    :param session: The session; its file is still writable (a plugin may add a group), and its
        instruments and simulators are already stopped.
    :param status: ``closed``, or ``aborted`` (an error or an operator's abort ended it).

    Called by :meth:`~mirrorlab.core.Session.close` for a session open for writing, before the
    status is stored; not called for a session opened read-only.
    """


# -- simulation ----------------------------------------------------------------------------------
@hookspec(firstresult=True)
def mirrorlab_read_motion(path: str, joints: list[str], scale: float, skip: int) -> tuple[Any, list[str], float] | None:
    """Read the joint positions of a motion recording for a simulated motion source.

    :param path: The recording (a path relative to the working directory), e.g. a BVH or marker file.
    :param joints: The joints to read, root to tip (in a marker file ``"A+B"`` is the midpoint of two
        markers).
    :param scale: mm per length unit of the file.
    :param skip: Leading frames to drop.
    :return: ``(positions, names, rate)``: positions ``(frames, joints, 3)`` in mm (NaN where missing),
        the joint names and the frame rate (Hz); ``None`` when this plugin does not read such a file.
        A plugin that reads the file's kind but cannot read this one raises a
        :class:`~mirrorlab.core.errors.MirrorlabError` naming the file and what is wrong.

    Called by the ``chain_source`` simulator for the recording its ``motion`` setting names, through
    :meth:`~mirrorlab.core.registry.Registry.first_result`, so that the instrument imports no plugin
    that reads recordings. ``firstresult``: the first answer that is not ``None`` is used, and an
    exception propagates to the simulator.
    """
