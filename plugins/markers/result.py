"""The result of one marker detection: centres and per-marker measures.

Pixel convention used throughout :mod:`mirrorlab.plugins.markers`: ``x`` runs to the right along a
row (the column index), ``y`` runs down (the row index), and the centre of pixel
``image[row, col]`` is at ``(x, y) = (col, row)``; the pixel covers ``col - 0.5 … col + 0.5``.
OpenCV's ``cv2.moments``, ``cv2.fitEllipse`` and ``cv2.projectPoints`` use the same convention.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def _readonly(a: NDArray) -> NDArray:
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


@dataclass(frozen=True)
class MarkerDetections:
    """Markers found in one image (K markers, in raster order of their first pixel).

    Attributes
    ----------
    xy : (K, 2) float, px
        Centres, ``x`` right and ``y`` down, pixel centres at integer coordinates.
    area : (K,) float, px²
        Number of pixels above the threshold in the marker's component.
    eccentricity : (K,) float
        :math:`\\sqrt{1-\\lambda_2/\\lambda_1}` of the weighted second moments (0 for a circle).
    contrast : (K,) float, grey levels
        Peak grey level in the marker minus the local background (median of a ring around it).
    covariance : (K, 2, 2) float, px²
        Centroid uncertainty ``cov / A`` (spec §1.2): second central moments divided by the area.
    axes : (K, 2) float, px
        Semi-major and semi-minor axes (``2 sqrt(λ)`` of the moments, or of the fitted ellipse).
    angle : (K,) float, rad
        Direction of the major axis from +x toward +y (image rows), in ``[0, π)``.
    method : str
        ``"subpixel"`` or ``"thesis"``.
    threshold : float
        Grey level used to binarise the image.
    """

    xy: FloatArray
    area: FloatArray
    eccentricity: FloatArray
    contrast: FloatArray
    covariance: FloatArray
    axes: FloatArray
    angle: FloatArray
    method: str
    threshold: float
    extra: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        for name in ("xy", "area", "eccentricity", "contrast", "covariance", "axes", "angle"):
            object.__setattr__(self, name, _readonly(np.asarray(getattr(self, name), dtype=np.float64)))

    def __len__(self) -> int:
        return int(self.xy.shape[0])

    @classmethod
    def empty(cls, method: str, threshold: float) -> MarkerDetections:
        """A result with no markers."""
        z = np.zeros(0)
        return cls(np.zeros((0, 2)), z, z, z, np.zeros((0, 2, 2)), np.zeros((0, 2)), z, method, threshold)
