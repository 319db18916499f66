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
        return [AcmeTracker]

Registration hooks return *classes*. The :class:`~mirrorlab.core.registry.Registry` calls them
through pluggy (``tryfirst`` / ``trylast`` and hook wrappers apply), checks each declaration (the
base class of its kind, name, version, description, typed parameters) and records which plugin
provided it, so that duplicates can be reported naming both providers.

Lifecycle hooks are notifications: they are called in the session's thread, must return
quickly and must not raise (an exception is logged against the plugin and the session goes on).
Live data never flows through hooks: subscribe to streams with
:meth:`mirrorlab.core.Session.subscribe` instead.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

import pluggy

if TYPE_CHECKING:
    from .algorithms import Algorithm, ResultRef
    from .controllers import Controller
    from .devices import Instrument
    from .session import Session
    from .steps import Step

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
    overrides :meth:`~mirrorlab.core.devices.Instrument.make_simulator`). A class of another kind
    makes the plugin broken, with a one-line error naming it.
    """


@hookspec
def mirrorlab_register_algorithms() -> list[type[Algorithm]]:
    """Return the algorithm classes this plugin provides.

    Each class subclasses :class:`mirrorlab.core.algorithms.Algorithm`: a pure function of its
    input arrays and typed parameters, runnable from the CLI, a recipe, the TUI or a script.
    """


@hookspec
def mirrorlab_register_controllers() -> list[type[Controller]]:
    """Return the controller classes this plugin provides.

    Each class subclasses :class:`mirrorlab.core.controllers.Controller`: live logic (a closed
    loop, a set-point schedule) that subscribes to streams and commands instruments while the
    session acquires, with everything it did recorded under ``/controllers/<label>``.
    """


@hookspec
def mirrorlab_register_steps() -> list[type[Step]]:
    """Return recipe step kinds (``[[steps]] action = "..."``) this plugin provides.

    Each class subclasses :class:`mirrorlab.core.steps.Step`, whose ``parameters`` validate the
    step's table in a recipe before anything runs.
    """


@hookspec
def mirrorlab_add_cli_commands(subparsers: argparse._SubParsersAction) -> None:
    """Add sub-commands to the ``mirrorlab`` CLI.

    Add a parser with ``subparsers.add_parser(name, help=...)`` and set its default ``func`` to a
    callable taking the parsed ``argparse.Namespace`` and returning an exit code (0 ok, 1 runtime
    failure, 2 usage or validation error).

    Called for entry-point plugins only when needed: for ``mirrorlab --help`` and when the command
    line names a command that is not built in (the built-in ones are listed without importing
    anything, see :mod:`mirrorlab.core.cli.commands`).
    """


# -- session lifecycle ---------------------------------------------------------------------------
@hookspec
def mirrorlab_session_opened(session: Session) -> None:
    """A session was created or opened (``session.writable`` tells which)."""


@hookspec
def mirrorlab_recording_started(session: Session) -> None:
    """Recording started: every instrument is acquiring and the file is in SWMR mode."""


@hookspec
def mirrorlab_recording_stopped(session: Session, statistics: dict[str, Any]) -> None:
    """Recording stopped; ``statistics`` maps ``"<instrument>/<stream>"`` to sample and drop counts."""


@hookspec
def mirrorlab_result_written(session: Session, result: ResultRef) -> None:
    """An algorithm run finished and its result group was written (``result.status`` ok or failed)."""


@hookspec
def mirrorlab_session_closing(session: Session, status: str) -> None:
    """The session is about to close with ``status`` (``closed`` or ``aborted``); the file is still writable."""


# -- simulation ----------------------------------------------------------------------------------
@hookspec(firstresult=True)
def mirrorlab_read_motion(path: str, joints: list[str], scale: float, skip: int) -> tuple[Any, list[str], float] | None:
    """Read the joint positions of a motion recording for a simulated motion source.

    The ``chain_source`` simulator plays the recording its ``motion`` setting names; the plugins that
    read recordings answer here, so that the instrument imports none of them. The first answer that
    is not ``None`` is used (:meth:`~mirrorlab.core.registry.Registry.first_result`).

    Parameters
    ----------
    path
        The recording (a path relative to the working directory), e.g. a BVH or marker file.
    joints
        The joints to read, root to tip (in a marker file ``"A+B"`` is the midpoint of two markers).
    scale
        mm per length unit of the file.
    skip
        Leading frames to drop.

    Returns
    -------
    tuple or None
        ``(positions, names, rate)``: positions ``(frames, joints, 3)`` mm (NaN where missing), the
        joint names and the frame rate (Hz); ``None`` when this plugin does not read such a file.
        A plugin that reads the file's kind but cannot read this one raises a
        :class:`~mirrorlab.core.errors.MirrorlabError` naming the file and what is wrong.
    """
