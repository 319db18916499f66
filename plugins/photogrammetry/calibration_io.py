"""Calibration input and output shared by the recipe steps and the CLI: chessboard photos to
``calibrate_pinhole`` inputs, a stored camera's datasets as reconstruction inputs, and storing a
calibration run under ``/calibration/<camera>``.
"""

from __future__ import annotations

import glob
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import Algorithm, SessionError

from .camera_arrays import CAMERA_KEYS, camera_kind
from .cameras import find_chessboard_corners
from .errors import CalibrationError, InvalidArgument

if TYPE_CHECKING:
    from mirrorlab.core import ResultRef, Session


def parse_pattern(text: str) -> tuple[int, int]:
    """``"10x7"`` -> (10, 7) inner corners (columns x rows).

    Examples
    --------
    >>> parse_pattern("10x7")
    (10, 7)
    """
    cols, sep, rows = text.lower().partition("x")
    try:
        out = (int(cols), int(rows))
    except ValueError:
        raise InvalidArgument(f"pattern {text!r} is not COLSxROWS (inner corners), e.g. 10x7") from None
    if not sep or min(out) < 2:
        raise InvalidArgument(f"pattern {text!r} is not COLSxROWS with at least 2x2 inner corners, e.g. 10x7")
    return out


def image_files(spec: str | Path) -> list[Path]:
    """Image files of a folder (``*.jpg *.jpeg *.png *.tif *.tiff *.bmp``, sorted) or of a glob pattern."""
    p = Path(spec)
    if p.is_dir():
        files = sorted(f for f in p.iterdir() if f.suffix.lower() in (".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp"))
    else:
        files = sorted(Path(f) for f in glob.glob(str(spec)))
    if not files:
        raise CalibrationError(f"no image files in {spec}; give a folder of chessboard photos or a glob such as 'cal/*.png'")
    return files


def chessboard_inputs(images: str | Path, pattern: str, square: float, detector: str = "classic"
                      ) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
    """Detect a chessboard in image files: the ``calibrate_pinhole`` inputs and what was found.

    Returns the inputs ``object_points`` (views, M, 3) mm, ``image_points`` (views, M, 2) px,
    ``image_size`` (2,) px and a dict ``{"found": [...], "missing": [...]}`` of file names.
    """
    det = find_chessboard_corners(image_files(images), parse_pattern(pattern), square, method=detector)
    return ({"object_points": np.stack(det.object_points).astype(float),
             "image_points": np.stack(det.image_points).astype(float),
             "image_size": np.asarray(det.image_size, dtype=np.int64)},
            {"found": [Path(f).name for f in det.found], "missing": [Path(f).name for f in det.missing]})


def store_calibration(session: Session, camera: str, ref: ResultRef, extra: Mapping[str, Any] | None = None,
                      attrs: Mapping[str, Any] | None = None) -> str:
    """Write the camera of a successful calibration run to ``/calibration/<camera>``.

    The group holds every output of the run (camera arrays under the input names of the
    reconstruction algorithms) plus ``extra`` arrays; its attributes name the ``result`` path, the
    ``algorithm``, the camera ``model`` and the run's ``parameters``.

    Raises
    ------
    CalibrationError
        The run failed (its error is repeated); nothing is written.
    """
    result = session.result(ref.require_ok(CalibrationError))
    arrays = {**result.outputs, **(extra or {})}
    path = f"calibration/{camera}"
    session.write_group(path, arrays, {"result": ref.path, "algorithm": ref.algorithm, "model": camera_kind(arrays),
                                       "parameters": result.attrs.get("parameters", {}), **(attrs or {})})
    return "/" + path


def require_new_camera(session: Session, camera: str) -> None:
    """Refuse early if ``/calibration/<camera>`` exists (groups are never overwritten)."""
    if not camera or "/" in camera:
        raise InvalidArgument(f"camera name {camera!r} must be a non-empty name without '/', e.g. 'cam'")
    if session.exists(f"calibration/{camera}"):
        raise SessionError(f"/calibration/{camera} already exists in {session.path}; choose another camera name")


def calibration_inputs(session: Session, group: str, algorithm: type[Algorithm]) -> dict[str, str]:
    """Dataset paths of a calibration group for the camera inputs ``algorithm`` declares."""
    key = group.strip("/")
    if not session.exists(key):
        raise SessionError(f"no calibration group {group} in {session.path}; run a calibrate step first "
                           "(`mirrorlab session tree FILE` lists the groups)")
    declared = {p.name for p in algorithm.inputs}
    return {name: f"/{key}/{name}" for name in session.members(key) if name in declared and name in CAMERA_KEYS}


