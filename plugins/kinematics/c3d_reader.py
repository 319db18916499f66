"""C3D parsing in a child process: a damaged C3D file must not crash or exhaust the caller.

Files written on Intel (processor type 84) and DEC (85) machines are read with ezc3d; MIPS/SGI
files (86: big-endian IEEE), which ezc3d refuses, with the pure-Python ``c3d`` package. The
processor type is byte 4 of the parameter section.

ezc3d (C++) trusts the sizes in a file's parameter section: a few flipped bits there make it
segfault or allocate gigabytes (seen while fuzzing a real file). :func:`read_c3d_arrays` therefore
parses in a separate Python process (about 0.2 s to start) under a memory limit and turns a
crash, a memory failure or a time-out into :class:`KinematicsIOError`. A plain subprocess, not
``multiprocessing``: that would re-import the caller's main script in the child.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import KinematicsIOError

#: Seconds a C3D file may take to parse (a 2 MB file takes about 0.1 s).
TIMEOUT_S = 120.0
#: Address space the child may add after importing ezc3d, bytes: generous for real files (ezc3d
#: holds each sample as an object, about 20x the file), far below what a damaged size field asks for.
MEMORY_BASE = 2 << 30
MEMORY_PER_FILE_BYTE = 64

_CHILD = """
import pickle, resource, sys
import numpy as np

path, extra = sys.argv[1], int(sys.argv[2])
with open("/proc/self/statm") as fh:
    limit = int(fh.read().split()[0]) * resource.getpagesize() + extra
soft, hard = resource.getrlimit(resource.RLIMIT_AS)
resource.setrlimit(resource.RLIMIT_AS, (limit if hard == resource.RLIM_INFINITY else min(limit, hard), hard))


def with_ezc3d():
    import ezc3d

    c = ezc3d.c3d(path)
    par = c["parameters"]["POINT"]
    labels = [str(x).strip() for x in par["LABELS"]["value"]]
    if "LABELS2" in par:
        labels += [str(x).strip() for x in par["LABELS2"]["value"]]
    return dict(labels=labels, rate=float(np.ravel(par["RATE"]["value"])[0]),
                units=[str(u) for u in (par["UNITS"]["value"] if "UNITS" in par else [])],
                points=np.asarray(c["data"]["points"], dtype=float),
                residuals=np.asarray(c["data"]["meta_points"]["residuals"], dtype=float),
                first_frame=int(c["header"]["points"]["first_frame"]))


def with_c3d_package():
    # ezc3d refuses MIPS (big-endian) files; the pure-Python c3d package reads them
    import itertools
    import warnings

    import c3d

    with open(path, "rb") as fh, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # it warns about absent analog data and end-of-file padding
        r = c3d.Reader(fh)
        labels = [str(x).strip() for x in r.point_labels]
        if r.get("POINT:LABELS2") is not None:
            labels += [str(x).strip() for x in r.get("POINT:LABELS2").string_array]
        units = r.get("POINT:UNITS")
        frames = r.get("POINT:FRAMES")
        n = int(frames.uint16_value) if frames is not None and frames.bytes_per_element == 2 else None
        if n is not None:  # read the frames the parameter section declares, as ezc3d does, whatever the header says
            r.header.last_frame = r.header.first_frame + n - 1
        rows = [p for _, p, _ in itertools.islice(r.read_frames(), n)]
        scale = r.point_scale
    data = np.stack(rows, axis=-1).astype(float) if rows else np.zeros((r.point_used, 5, 0))  # (M, 5, T)
    xyz = data[:, :3]
    if scale > 0:
        # integer storage: c3d rounds word * scale to float32; ezc3d keeps the exact product
        xyz = np.round(xyz / scale) * scale
    points = np.concatenate([np.transpose(xyz, (1, 0, 2)), np.ones((1,) + xyz.shape[::2])])
    return dict(labels=labels, rate=float(r.point_rate),
                units=[str(units.string_value).strip()] if units is not None else [],
                points=points, residuals=data[None, :, 3], first_frame=int(r.header.first_frame) - 1)


try:
    with open(path, "rb") as fh:
        block = fh.read(1)
        fh.seek(max(block[0] - 1, 0) * 512 if block else 0)
        processor = fh.read(4)[3:4]
    out = ("ok", with_c3d_package() if processor == bytes([86]) else with_ezc3d())
except Exception as exc:  # the readers raise plain RuntimeError/OSError/ValueError/AssertionError; keys may be missing
    out = ("error", f"{type(exc).__name__}: {exc}")
sys.stdout.buffer.write(pickle.dumps(out))
"""


@dataclass
class C3DArrays:
    """What :func:`~.io.read_c3d` needs from the file.

    ``points`` (4, M, T) in the file's unit, ``residuals`` (1, M, T) or empty, ``first_frame``
    0-based, ``units`` the ``POINT:UNITS`` values (empty when the parameter is absent).
    """

    labels: list[str]
    rate: float
    units: list[str]
    points: np.ndarray
    residuals: np.ndarray
    first_frame: int


def read_c3d_arrays(path: Path) -> C3DArrays:
    """Parse ``path`` with ezc3d (or, for a MIPS file, the ``c3d`` package) in a child process.

    Raises
    ------
    KinematicsIOError
        The reader rejected the file, crashed on it, ran out of its memory allowance or took longer
        than :data:`TIMEOUT_S`; the message names the file.
    """
    extra = MEMORY_BASE + MEMORY_PER_FILE_BYTE * path.stat().st_size
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    try:
        proc = subprocess.run([sys.executable, "-c", _CHILD, str(path), str(extra)], capture_output=True,
                              timeout=TIMEOUT_S, env=env)
    except subprocess.TimeoutExpired:
        raise KinematicsIOError(f"{path}: reading the C3D file took longer than {TIMEOUT_S:g} s; the file is "
                                "damaged or not a C3D file") from None
    if proc.returncode != 0 or not proc.stdout:
        detail = proc.stderr.decode(errors="replace").strip().splitlines()[-1:] or [f"exit code {proc.returncode}"]
        raise KinematicsIOError(f"{path}: the C3D reader (ezc3d) crashed on this file ({detail[0][:120]}); the "
                                "file is damaged: copy it again from its source")
    status, value = pickle.loads(proc.stdout)
    if status != "ok":
        raise KinematicsIOError(f"{path}: not a readable C3D file ({value}); check that it is a complete, "
                                "undamaged C3D file")
    return C3DArrays(**value)
