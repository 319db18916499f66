"""mirrorlab core: sessions, plugins, the HDF5 store, recipes, CLI.

Public API::

    from mirrorlab.core import Session, hookimpl, Parameter, ParameterSet, get_registry
"""

from .algorithms import Algorithm, Port, ResultRef, RunContext
from .errors import (
    AlgorithmError,
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
from .hookspecs import hookimpl
from .params import Parameter, ParameterSet
from .registry import get_registry
from .session import Session
from .streams import StreamSpec

__all__ = [
    "Algorithm", "AlgorithmError", "DamagedFileError", "DeviceDisconnected", "DeviceError", "DeviceReplyError", "DeviceTimeout",
    "DuplicateNameError", "MirrorlabError", "Parameter", "ParameterSet", "PluginError", "Port", "Problem",
    "ProtocolError", "ResultRef", "RunContext", "Session", "SessionError", "StreamSpec", "ValidationError",
    "get_registry", "hookimpl",
]
