"""Camera models as named arrays: how calibrations travel through sessions, recipes, JSON and the CLI.

A calibrated camera is stored as a small set of arrays whose names are also the input names of the
reconstruction algorithms, so a ``/calibration/<camera>`` group (or the JSON printed by
``mirrorlab calibrate --json``) can be handed to them as it is:

* plane calibration (thesis §3.2.3, :class:`~.cameras.PlaneCalibration`): ``plane_coefficients``
  ((6, 2) quadratic, or (8 + k,) homography + k radial terms, on normalised image coordinates),
  ``plane_center`` (2,) and ``plane_scale`` () (image normalisation, image units), ``plane_z`` () mm,
  ``camera_center`` (3,) mm;
* pinhole (OpenCV, :class:`~.cameras.PinholeCamera`): ``camera_matrix`` (3, 3) px, ``dist_coeffs``
  (k,), ``rotation`` (3, 3) world -> camera, ``translation`` (3,) mm (and ``camera_center`` (3,) mm,
  derived).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .cameras import PinholeCamera, PlaneCalibration
from .errors import InvalidArgument

__all__ = ["PLANE_KEYS", "PINHOLE_KEYS", "CAMERA_KEYS", "plane_arrays", "pinhole_arrays", "camera_from_arrays",
           "camera_kind"]

PLANE_KEYS = ("plane_coefficients", "plane_center", "plane_scale", "plane_z", "camera_center")
PINHOLE_KEYS = ("camera_matrix", "dist_coeffs", "rotation", "translation")
#: Every name a camera may be given by (the optional camera inputs of the reconstruction algorithms).
CAMERA_KEYS = tuple(dict.fromkeys(PLANE_KEYS + PINHOLE_KEYS))


def plane_arrays(cal: PlaneCalibration) -> dict[str, NDArray[np.float64]]:
    """The arrays that define a plane calibration (see the module docstring).

    Examples
    --------
    >>> from mirrorlab.plugins.photogrammetry.cameras import fit_plane_calibration
    >>> g = np.mgrid[-2:3, -2:3].reshape(2, -1).T * 100.0
    >>> sorted(plane_arrays(fit_plane_calibration(g / 10, g, 0.0, [0, 0, 1000.0])))
    ['camera_center', 'plane_center', 'plane_coefficients', 'plane_scale', 'plane_z']
    """
    return {"plane_coefficients": np.asarray(cal.params, float), "plane_center": np.asarray(cal.center, float),
            "plane_scale": np.float64(cal.scale), "plane_z": np.float64(cal.plane_z),
            "camera_center": np.asarray(cal.camera_center, float)}


def pinhole_arrays(cam: PinholeCamera) -> dict[str, NDArray[np.float64]]:
    """The arrays that define a pinhole camera, plus its derived ``camera_center``."""
    return {"camera_matrix": np.asarray(cam.K, float), "dist_coeffs": np.asarray(cam.dist, float).ravel(),
            "rotation": np.asarray(cam.R, float), "translation": np.asarray(cam.t, float).reshape(3),
            "camera_center": cam.camera_center}


def camera_kind(arrays: Mapping[str, Any]) -> str:
    """``"pinhole"``, ``"quadratic"`` or ``"projective"`` from the names (and shapes) present.

    Raises
    ------
    InvalidArgument
        Neither set of arrays is complete; the message lists what is missing.
    """
    have = {k for k, v in arrays.items() if v is not None}
    if "camera_matrix" in have:
        missing = [k for k in PINHOLE_KEYS if k not in have]
        if missing:
            raise InvalidArgument(f"pinhole camera: missing {', '.join(missing)}; give all of {', '.join(PINHOLE_KEYS)}")
        return "pinhole"
    if "plane_coefficients" in have:
        missing = [k for k in PLANE_KEYS if k not in have]
        if missing:
            raise InvalidArgument(f"plane calibration: missing {', '.join(missing)}; give all of {', '.join(PLANE_KEYS)}")
        coef = np.asarray(arrays["plane_coefficients"])
        if coef.shape == (6, 2):
            return "quadratic"
        if coef.ndim == 1 and coef.size >= 8:
            return "projective"
        raise InvalidArgument(f"plane_coefficients must have shape (6, 2) (quadratic) or (8 + k,) (projective), "
                              f"got {coef.shape}")
    raise InvalidArgument("no camera given: pass plane_coefficients, plane_center, plane_scale, plane_z and "
                          "camera_center (mirrorlab calibrate --points), or camera_matrix, dist_coeffs, rotation and "
                          "translation (mirrorlab calibrate --images)")


def camera_from_arrays(arrays: Mapping[str, Any]) -> PlaneCalibration | PinholeCamera:
    """Rebuild a camera model (with ``camera_center``, ``rays``, ``project``) from its arrays.

    Examples
    --------
    >>> cam = camera_from_arrays({"camera_matrix": [[1000., 0, 320], [0, 1000., 240], [0, 0, 1]],
    ...                           "dist_coeffs": np.zeros(5), "rotation": np.eye(3), "translation": [0., 0., 0.]})
    >>> cam.project([[0.0, 0.0, 1000.0]]).tolist()
    [[320.0, 240.0]]
    """
    kind = camera_kind(arrays)
    if kind == "pinhole":
        return PinholeCamera(np.asarray(arrays["camera_matrix"], float).reshape(3, 3),
                             np.asarray(arrays["dist_coeffs"], float).ravel(),
                             np.asarray(arrays["rotation"], float).reshape(3, 3),
                             np.asarray(arrays["translation"], float).reshape(3))
    coef = np.asarray(arrays["plane_coefficients"], float)
    return PlaneCalibration(
        model=kind, plane_z=float(np.asarray(arrays["plane_z"])), camera_center=np.asarray(arrays["camera_center"],
                                                                                             float).reshape(3),
        params=coef, center=np.asarray(arrays["plane_center"], float).reshape(2),
        scale=float(np.asarray(arrays["plane_scale"])), residuals=np.zeros((0, 2)), rms=float("nan"),
        max_residual=float("nan"), condition=float("nan"), image_xy=np.zeros((0, 2)),
        n_radial=0 if kind == "quadratic" else coef.size - 8,
    )
