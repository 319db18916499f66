"""ezc3d in a child process: a damaged C3D file must not crash or exhaust the caller.

ezc3d (C++) trusts the sizes in a file's parameter section: a few flipped bits there make it
segfault or allocate gigabytes (seen while fuzzing a real file). :func:`read_c3d_arrays` therefore
parses in a child forked from a forkserver (cheap after the first call) under a memory limit, and
turns a crash, a memory failure or a time-out into :class:`KinematicsIOError`.
"""

from __future__ import annotations

import multiprocessing
import resource
from dataclasses import dataclass
from multiprocessing.connection import Connection
from pathlib import Path

import numpy as np

from .errors import KinematicsIOError

#: Seconds a C3D file may take to parse (a 2 MB file takes about 0.1 s).
TIMEOUT_S = 120.0
#: Address space the child may add beyond its start, bytes: generous for real files (ezc3d holds
#: each sample as an object, about 20x the file), far below what a damaged size field asks for.
MEMORY_BASE = 2 << 30
MEMORY_PER_FILE_BYTE = 64

_CONTEXT = multiprocessing.get_context("forkserver")
_CONTEXT.set_forkserver_preload(["ezc3d", "numpy", __name__])


@dataclass
class C3DArrays:
    """What :func:`~.io.read_c3d` needs from ezc3d; points (4, M, T), residuals (1, M, T) or empty."""

    labels: list[str]
    rate: float
    units: list[str]
    points: np.ndarray
    residuals: np.ndarray
    first_frame: int


def _parse(path: str) -> C3DArrays:
    import ezc3d

    c = ezc3d.c3d(path)
    par = c["parameters"]["POINT"]
    labels = [str(x).strip() for x in par["LABELS"]["value"]]
    if "LABELS2" in par:
        labels += [str(x).strip() for x in par["LABELS2"]["value"]]
    return C3DArrays(labels, float(np.ravel(par["RATE"]["value"])[0]),
                     [str(u) for u in (par["UNITS"]["value"] if "UNITS" in par else [])],
                     np.asarray(c["data"]["points"], dtype=float),
                     np.asarray(c["data"]["meta_points"]["residuals"], dtype=float),
                     int(c["header"]["points"]["first_frame"]))


def _child(path: str, limit: int, conn: Connection) -> None:
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    if soft == resource.RLIM_INFINITY or soft > limit:
        resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    try:
        conn.send(("ok", _parse(path)))
    except Exception as exc:  # ezc3d raises plain RuntimeError/OSError/ValueError; keys may be missing
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
    finally:
        conn.close()


def _address_space() -> int:
    """This process's virtual memory size, bytes (the child starts from a copy of the forkserver)."""
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[0]) * resource.getpagesize()


def read_c3d_arrays(path: Path) -> C3DArrays:
    """Parse ``path`` with ezc3d in a child process.

    Raises
    ------
    KinematicsIOError
        ezc3d rejected the file, crashed on it, ran out of its memory allowance or took longer
        than :data:`TIMEOUT_S`; the message names the file.
    """
    limit = _address_space() + MEMORY_BASE + MEMORY_PER_FILE_BYTE * path.stat().st_size
    receive, send = _CONTEXT.Pipe(duplex=False)
    child = _CONTEXT.Process(target=_child, args=(str(path), limit, send), daemon=True)
    child.start()
    send.close()
    try:
        if not receive.poll(TIMEOUT_S):
            child.kill()
            raise KinematicsIOError(f"{path}: reading the C3D file took longer than {TIMEOUT_S:g} s; "
                                    "the file is damaged or not a C3D file")
        status, value = receive.recv()
    except EOFError:  # the child died without answering: ezc3d crashed on the file
        child.join()
        raise KinematicsIOError(f"{path}: the C3D reader (ezc3d) crashed on this file (exit code "
                                f"{child.exitcode}); the file is damaged: copy it again from its source") from None
    finally:
        receive.close()
        child.join(timeout=5.0)
    if status != "ok":
        raise KinematicsIOError(f"{path}: not a readable C3D file ({value}); check that it is a complete, "
                                "undamaged C3D file")
    return value
