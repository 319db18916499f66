"""Shape measures from weighted second moments, vectorised over markers."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def shape_from_moments(m00: FloatArray, mu20: FloatArray, mu11: FloatArray, mu02: FloatArray,
                       area: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Eccentricity, semi-axes, major-axis angle and centroid covariance of K weighted blobs.

    Parameters
    ----------
    m00 : (K,) total weight; mu20, mu11, mu02 : (K,) central moments (weights × px²).
    area : (K,) number of pixels (the ``A`` of ``cov / A``, spec §1.2).

    Returns
    -------
    eccentricity : (K,) in [0, 1); axes : (K, 2) px (``2 sqrt(λ)``, exact for a uniform ellipse);
    angle : (K,) rad in [0, π); covariance : (K, 2, 2) px².

    Examples
    --------
    >>> e, axes, angle, cov = shape_from_moments(np.array([1.0]), np.array([4.0]), np.array([0.0]),
    ...                                          np.array([1.0]), np.array([10.0]))
    >>> round(float(e[0]), 4), axes.round(3).tolist(), float(angle[0])
    (0.866, [[4.0, 2.0]], 0.0)
    """
    a, b, c = mu20 / m00, mu11 / m00, mu02 / m00
    half_tr, diff = 0.5 * (a + c), np.hypot(0.5 * (a - c), b)
    lam1, lam2 = half_tr + diff, np.maximum(half_tr - diff, 0.0)
    ratio = np.divide(lam2, lam1, out=np.ones_like(lam1), where=lam1 > 0)
    ecc = np.sqrt(np.clip(1.0 - ratio, 0.0, 1.0))
    angle = np.mod(0.5 * np.arctan2(2.0 * b, a - c), np.pi)
    axes = np.empty((len(a), 2))
    axes[:, 0], axes[:, 1] = 2.0 * np.sqrt(lam1), 2.0 * np.sqrt(lam2)
    cov = np.empty((len(a), 2, 2))
    area = np.asarray(area, float)
    cov[:, 0, 0], cov[:, 0, 1], cov[:, 1, 1] = a / area, b / area, c / area
    cov[:, 1, 0] = cov[:, 0, 1]
    return ecc, axes, angle, cov
