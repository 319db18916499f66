"""mirrorlab core: sessions, plugins, the HDF5 store, recipes, CLI.

Public API::

    from mirrorlab.core import Session, hookimpl, Parameter, ParameterSet, get_registry

Names other than the errors are imported on first use (PEP 562), so that light entry points such
as ``mirrorlab --version`` (``mirrorlab.core.cli``) do not pay for numpy and h5py.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .errors import (
    AlgorithmError,
    AlgorithmInputError,
    Cancelled,
    DamagedFileError,
    DeviceDisconnected,
    DeviceError,
    DeviceReplyError,
    DeviceTimeout,
    DuplicateNameError,
    MirrorlabError,
    PluginError,
    Problem,
    ProtocolError,
    SessionError,
    ValidationError,
)

if TYPE_CHECKING:
    from .algorithms import Algorithm, Port, ResultRef, RunContext
    from .hookspecs import hookimpl
    from .params import Parameter, ParameterSet
    from .registry import get_registry
    from .session import Session
    from .streams import StreamSpec

#: Public name -> the sub-module that defines it (imported when the name is first used).
_LAZY = {"Algorithm": "algorithms", "Port": "algorithms", "ResultRef": "algorithms", "RunContext": "algorithms",
         "hookimpl": "hookspecs", "Parameter": "params", "ParameterSet": "params", "get_registry": "registry",
         "Session": "session", "StreamSpec": "streams"}

__all__ = [
    "Algorithm", "AlgorithmError", "AlgorithmInputError", "Cancelled", "DamagedFileError", "DeviceDisconnected", "DeviceError",
    "DeviceReplyError", "DeviceTimeout",
    "DuplicateNameError", "MirrorlabError", "Parameter", "ParameterSet", "PluginError", "Port", "Problem",
    "ProtocolError", "ResultRef", "RunContext", "Session", "SessionError", "StreamSpec", "ValidationError",
    "get_registry", "hookimpl",
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(__all__))
