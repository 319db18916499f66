"""Typed errors shared by every part of mirrorlab.

Every error message says what went wrong *and* what to do about it. Algorithm packages derive
their own errors from :class:`MirrorlabError` (for example ``mirrorlab.plugins.photogrammetry``'s
``CalibrationError``) so that the CLI can report any of them as one clear line.
"""

from __future__ import annotations

from pathlib import Path


class MirrorlabError(Exception):
    """Base class of every error mirrorlab raises on purpose."""


class MirrorlabWarning(UserWarning):
    """Something the user must know that does not stop the work (a file holding less than it
    declares, say). The CLI prints it as one ``mirrorlab: warning:`` line."""


class ValidationError(MirrorlabError):
    """Input (a recipe, parameters, a CLI option) failed validation.

    ``problems`` holds one :class:`Problem` per defect so that all of them can be reported at once.
    """

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = list(problems)
        super().__init__("\n".join(str(p) for p in self.problems))


class Problem:
    """One validation defect: where it is (file, key path; ``key=""`` for the whole file) and why it is wrong."""

    __slots__ = ("file", "key", "reason")

    def __init__(self, key: str, reason: str, file: str | None = None) -> None:
        self.file = file
        self.key = key
        self.reason = reason

    def __str__(self) -> str:
        where = "".join(f"{part}: " for part in (self.file, self.key) if part)  # a whole-file problem has no key
        return f"{where}{self.reason}"

    def __repr__(self) -> str:
        return f"Problem({self.key!r}, {self.reason!r}, file={self.file!r})"


class PluginError(MirrorlabError):
    """A plugin could not be found, loaded or registered, or two plugins claim one name."""


class DuplicateNameError(PluginError):
    """Two providers register the same instrument, algorithm or step name."""


class SessionError(MirrorlabError):
    """A session file is missing, of the wrong schema, read-only, or in the wrong state."""


class DamagedFileError(SessionError):
    """A session file is truncated, bit-damaged or not HDF5 at all: HDF5 cannot read it."""


class SessionExistsError(SessionError):
    """A new session would replace an existing file.

    ``advice`` says what to do; the API's default names ``overwrite=True``, the CLI rewords it for
    its ``--overwrite`` option.
    """

    def __init__(self, path: Path, advice: str = "pass overwrite=True to replace it, or choose another path") -> None:
        self.path = path
        super().__init__(f"{path} already exists; {advice}")


class DataError(MirrorlabError):
    """Input data is damaged (a cut file, a frame that cannot be decoded): retrying cannot help.

    An instrument whose source raises it during acquisition stops and reports it once, instead of
    reconnecting as it does for a lost connection.
    """


class StoppedOnRequest(MirrorlabError):
    """Work ended early because :meth:`Session.request_stop` (or Ctrl-C) asked it to; what was
    done is kept."""


class AlgorithmError(MirrorlabError):
    """An algorithm failed on its inputs (degenerate geometry, singular fit, ...)."""


class Cancelled(MirrorlabError):
    """Stopped on request: :meth:`Session.request_stop` (or a run's cancel event) asked the work to end.

    Not a failure: a cancelled algorithm run is stored with ``status = "cancelled"`` and no outputs.
    """


class AlgorithmInputError(ValidationError, AlgorithmError):
    """The inputs given to an algorithm do not match its declared ports (unknown or missing names).

    A validation error (the CLI exits 2) that is also an :class:`AlgorithmError`.
    """


class DeviceError(MirrorlabError):
    """Base class of instrument errors."""


class DeviceTimeout(DeviceError):
    """A device did not answer within its timeout."""


class DeviceDisconnected(DeviceError):
    """The connection to a device was lost or could not be opened."""


class ProtocolError(DeviceError):
    """A device sent bytes that do not follow its protocol (garbage, wrong reply shape)."""


class ConfigurationError(DeviceError):
    """A device or source cannot work as configured (no such folder, the port holds another kind
    of device): retrying cannot help, so an acquiring instrument stops at once; fix the setting."""


class DeviceReplyError(DeviceError):
    """A device answered a command with ``ERR <code> <text>``."""

    def __init__(self, command: str, code: str, text: str, device: str = "device") -> None:
        self.command = command
        self.code = code
        self.text = text
        super().__init__(f"{device} answered {command!r} with {code} {text}")
