"""Marker detection (spec analysis.md §1): the thesis's weighted-filter hill climbing and a sub-pixel centroid.

Pixel convention: ``x`` right (column index), ``y`` down (row index), the centre of pixel
``image[row, col]`` at ``(x, y) = (col, row)``.

>>> import numpy as np
>>> from mirrorlab.plugins.markers import detect_markers
>>> img = np.zeros((40, 40), np.uint8); img[10:15, 20:25] = 255
>>> detect_markers(img).xy.tolist()
[[22.0, 12.0]]
"""

from .detect import METHODS, auto_threshold, detect_markers, grey_image
from .errors import InvalidDetectionParameter, InvalidImage, MarkerError
from .result import MarkerDetections
from .stream import detect_stream
from .thesis import DEFAULT_WEIGHTS, thesis_centres

__all__ = ["DEFAULT_WEIGHTS", "METHODS", "InvalidDetectionParameter", "InvalidImage", "MarkerDetections",
           "MarkerError", "auto_threshold", "detect_markers", "detect_stream", "grey_image", "thesis_centres"]
