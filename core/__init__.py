"""mirrorlab core: sessions, plugins, the HDF5 store, recipes, CLI.

Public API::

    from mirrorlab.core import Session, hookimpl, Parameter, ParameterSet, get_registry

Plugins import what they need from here (and instrument drivers from ``mirrorlab.core.devices``),
never from the core's internal modules: besides the classes above, the recipe ``Step`` base and
its helpers, ``execute`` (run an algorithm without a session), the CLI helpers of plugin commands
(``Subcommands``, what ``mirrorlab_add_cli_commands`` receives, ``add_parameter_options``,
``parameter_type``, ``collected``, ``plain``, ``existing_path``, ``add_overwrite_option``,
``progress_bar``), ``ScreenEntry`` (a console screen, see also ``mirrorlab.core.tui``),
``SessionClock``, ``EventBus`` and the file ``schema``.

Names other than the errors are imported on first use (PEP 562), so that light entry points such
as ``mirrorlab --version`` (``mirrorlab.core.cli``) do not pay for numpy and h5py.

A session's file is read through the ``Session`` read API (``read``, ``attributes``, ``tree``,
``stream``, ``results``...; its ``Node``, ``StreamData`` and ``ResultData``), never through h5py;
``is_hdf5`` says whether a file is HDF5 at all.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .errors import (
    AlgorithmError,
    AlgorithmInputError,
    Cancelled,
    ConfigurationError,
    DamagedFileError,
    DataError,
    DeviceDisconnected,
    DeviceError,
    DeviceReplyError,
    DeviceTimeout,
    DuplicateNameError,
    MirrorlabError,
    MirrorlabWarning,
    PluginError,
    Problem,
    ProtocolError,
    SessionError,
    SessionExistsError,
    StoppedOnRequest,
    ValidationError,
)

if TYPE_CHECKING:
    from .algorithms import Algorithm, Port, ResultRef, RunContext, execute
    from .cli.commands import Subcommands
    from .cli.options import add_parameter_options, collected, existing_path, parameter_type, plain
    from .cli.outputs import add_overwrite_option
    from .cli.progress import progress_bar
    from .clock import SessionClock
    from .controller_runtime import ControllerContext
    from .controllers import Controller
    from .events import EventBus
    from .figures import figures_folder, save_figure
    from .hookspecs import hookimpl
    from .params import Parameter, ParameterSet, identifier_problem
    from .registry import Registry, get_registry
    from .session import Node, ResultData, Session, StreamData
    from .steps import ALGORITHM_TABLES, AlgorithmStep, Step, algorithm_tables
    from .store import schema
    from .store.files import is_hdf5
    from .streams import Block, StreamSpec
    from .tui.screens import ScreenEntry

#: Public name -> the sub-module that defines it (imported when the name is first used).
_LAZY = {"Algorithm": "algorithms", "Port": "algorithms", "ResultRef": "algorithms", "RunContext": "algorithms",
         "execute": "algorithms", "hookimpl": "hookspecs", "Parameter": "params", "ParameterSet": "params",
         "identifier_problem": "params", "get_registry": "registry", "Registry": "registry", "Session": "session",
         "ResultData": "session",
         "StreamData": "session", "Node": "session", "is_hdf5": "store.files",
         "StreamSpec": "streams", "Block": "streams", "Controller": "controllers",
         "ControllerContext": "controller_runtime", "Step": "steps", "ALGORITHM_TABLES": "steps",
         "algorithm_tables": "steps", "AlgorithmStep": "steps", "SessionClock": "clock", "EventBus": "events",
         "figures_folder": "figures", "save_figure": "figures",
         "add_parameter_options": "cli.options", "collected": "cli.options", "existing_path": "cli.options",
         "parameter_type": "cli.options", "plain": "cli.options", "add_overwrite_option": "cli.outputs",
         "progress_bar": "cli.progress", "schema": "store.schema", "Subcommands": "cli.commands",
         "ScreenEntry": "tui.screens"}

__all__ = [
    "ALGORITHM_TABLES", "Algorithm", "AlgorithmError", "AlgorithmInputError", "AlgorithmStep", "Block", "Cancelled",
    "ConfigurationError",
    "Controller", "ControllerContext", "DamagedFileError", "DataError", "DeviceDisconnected", "DeviceError",
    "DeviceReplyError", "DeviceTimeout", "DuplicateNameError", "EventBus", "MirrorlabError", "MirrorlabWarning",
    "Parameter", "ParameterSet", "PluginError", "Port", "Problem", "ProtocolError", "Registry", "ResultData",
    "ResultRef", "RunContext", "ScreenEntry", "Session", "SessionClock", "SessionError", "SessionExistsError", "Step",
    "StoppedOnRequest", "StreamSpec", "Subcommands", "ValidationError", "add_overwrite_option", "add_parameter_options",
    "algorithm_tables", "collected", "execute", "existing_path", "get_registry", "hookimpl", "parameter_type", "plain",
    "figures_folder", "identifier_problem", "progress_bar", "save_figure", "schema",
    "Node", "StreamData", "is_hdf5",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    imported = importlib.import_module(f".{module}", __name__)
    value = imported if module.endswith(f".{name}") else getattr(imported, name)  # a module (``schema``) or a name
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
