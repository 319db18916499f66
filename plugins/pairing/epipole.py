"""The mirror epipole: the image of the virtual camera centre (spec photogrammetry.md §7).

A marker ``X`` and its mirror image ``X' = X - 2((X-G)·n) n`` lie on a line parallel to the mirror
normal, and so does the camera pair ``F1, F2``; the image of that direction's vanishing point is
the image of ``F2``. Every marker and its mirror image therefore lie on one line through this
*mirror epipole* (in the undistorted image). Its homogeneous third coordinate keeps its sign:
``> 0`` when ``F2`` lies in front of the camera, and then the virtual image always lies between
the real image and the epipole.
"""

from __future__ import annotations

import cv2
import numpy as np
from mirrorlab.plugins.photogrammetry import virtual_camera
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidPairingInput


def projection_matrix(K: ArrayLike, R: ArrayLike, t: ArrayLike) -> NDArray[np.float64]:
    """``P = K [R | t]`` (3, 4) of a pinhole camera (world → camera ``R x + t``)."""
    return np.asarray(K, float) @ np.c_[np.asarray(R, float), np.asarray(t, float).reshape(3)]


def mirror_epipole(P: ArrayLike, camera_center: ArrayLike, mirror_point: ArrayLike,
                   normal: ArrayLike) -> NDArray[np.float64]:
    """Homogeneous mirror epipole ``P [F2; 1]`` (3,), sign kept (see the module notes).

    Parameters
    ----------
    P : (3, 4) projection matrix of the real camera (``K [R | t]``), pixels.
    camera_center : (3,) ``F1``, mm.
    mirror_point : (3,) ``G`` on the reflecting surface, mm.
    normal : (3,) mirror normal toward the camera.

    Returns
    -------
    (3,) homogeneous pixel coordinates, normalised to unit length; divide by ``e[2]`` for pixels.

    Examples
    --------
    >>> P = projection_matrix(np.diag([1000., 1000., 1.]), np.eye(3), np.zeros(3))
    >>> e = mirror_epipole(P, [0., 0., 0.], [100., 0., 1000.], [-0.6, 0., -0.8])
    >>> np.round(e[:2] / e[2], 6).tolist()
    [750.0, 0.0]
    """
    P = np.asarray(P, float)
    if P.shape != (3, 4):
        raise InvalidPairingInput(f"P must be a (3, 4) projection matrix, got shape {P.shape}")
    F2 = virtual_camera(camera_center, mirror_point, normal).center
    e = P @ np.r_[F2, 1.0]
    return e / np.linalg.norm(e)


def undistort_points(xy: ArrayLike, K: ArrayLike, dist: ArrayLike) -> NDArray[np.float64]:
    """Pixel coordinates with lens distortion removed (``cv2.undistortPoints`` with ``P = K``).

    Epipolar lines are straight only in the undistorted image; NaN rows stay NaN.

    Examples
    --------
    >>> undistort_points([[320., 240.]], np.array([[500., 0, 320], [0, 500., 240], [0, 0, 1]]), np.zeros(5)).tolist()
    [[320.0, 240.0]]
    """
    p = np.asarray(xy, float).reshape(-1, 2)
    out = np.full_like(p, np.nan)
    ok = np.all(np.isfinite(p), axis=1)
    if ok.any():
        K = np.asarray(K, float)
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
        out[ok] = cv2.undistortPoints(p[ok].reshape(-1, 1, 2), K, np.asarray(dist, float), None, None, K,
                                          crit).reshape(-1, 2)
    return out
