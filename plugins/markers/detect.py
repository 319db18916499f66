"""``detect_markers``: one entry point for both detectors, with input checks and thresholding."""

from __future__ import annotations

from typing import Literal

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidDetectionParameter, InvalidImage
from .moments import shape_from_moments
from .result import MarkerDetections
from .subpixel import RING, Labeling, subpixel_centroids
from .thesis import thesis_centres

Method = Literal["subpixel", "thesis"]
METHODS = ("subpixel", "thesis")


def grey_image(image: ArrayLike, *, polarity: str = "bright", where: str = "image") -> NDArray:
    """Validate ``image`` and return a 2-D grey array (uint8, uint16 or float32) with bright markers.

    Colour images (H, W, 3|4) are read as BGR(A) and converted with ``cv2.cvtColor``; boolean
    images become 0/255; ``polarity="dark"`` inverts the grey levels (dark markers on a bright
    background).

    Examples
    --------
    >>> grey_image(np.array([[0, 1], [1, 0]], bool)).tolist()
    [[0, 255], [255, 0]]
    """
    a = np.asarray(image)
    if a.dtype == bool:
        a = a.astype(np.uint8) * np.uint8(255)
    if a.ndim == 3 and a.shape[2] in (3, 4) and a.dtype in (np.uint8, np.uint16, np.float32):
        a = cv2.cvtColor(a, cv2.COLOR_BGR2GRAY if a.shape[2] == 3 else cv2.COLOR_BGRA2GRAY)
    if a.ndim != 2:
        raise InvalidImage(f"{where}: expected a 2-D grey image (H, W) or a BGR image (H, W, 3), got shape "
                           f"{a.shape} {a.dtype}; pass one frame at a time")
    if a.size == 0:
        raise InvalidImage(f"{where}: the image is empty (shape {a.shape})")
    if a.dtype not in (np.uint8, np.uint16):
        if not np.issubdtype(a.dtype, np.number):
            raise InvalidImage(f"{where}: unsupported pixel type {a.dtype}; use uint8, uint16 or float")
        a = a.astype(np.float32)
        if not np.all(np.isfinite(a)):
            raise InvalidImage(f"{where}: the image contains NaN or infinite pixels; replace them first")
    if polarity not in ("bright", "dark"):
        raise InvalidDetectionParameter(f"polarity must be 'bright' or 'dark', got {polarity!r}")
    return a if polarity == "bright" else inversion_level(a) - a


def inversion_level(a: NDArray) -> float:
    """The constant ``c`` of the inversion ``c - I`` used for dark markers (type maximum, or image maximum)."""
    return float(np.iinfo(a.dtype).max) if a.dtype != np.float32 else float(a.max())


def auto_threshold(image: NDArray) -> float:
    """Otsu's threshold (``cv2.threshold`` with ``THRESH_OTSU``); pixels ``> T`` are markers.

    On a two-level (binary) image it returns the lower level, on a uniform image its level (no
    markers). Float images are scaled to 16 bits for the histogram.

    Examples
    --------
    >>> auto_threshold(np.array([[0, 255], [255, 0]], np.uint8))
    0.0
    """
    lo, hi = cv2.minMaxLoc(image)[:2] if image.dtype != np.float32 else (float(image.min()), float(image.max()))
    if hi <= lo:
        return float(hi)
    if image.dtype == np.uint8 and (hi - lo < 2 or not cv2.countNonZero(cv2.inRange(image, lo + 1, hi - 1))):
        return float(lo)  # two levels (a binary frame): what Otsu returns, without the histogram
    if image.dtype in (np.uint8, np.uint16):
        return float(cv2.threshold(image, 0, 1, cv2.THRESH_BINARY | cv2.THRESH_OTSU)[0])
    scaled = np.rint((image - lo) * (65535.0 / (hi - lo))).astype(np.uint16)
    return lo + (hi - lo) * float(cv2.threshold(scaled, 0, 1, cv2.THRESH_BINARY | cv2.THRESH_OTSU)[0]) / 65535.0


def _binarise(image: NDArray, threshold: float) -> NDArray[np.uint8]:
    if image.dtype == np.uint8:
        return cv2.threshold(image, threshold, 255, cv2.THRESH_BINARY)[1]
    return (image > threshold).astype(np.uint8) * np.uint8(255)


def _box_properties(image: NDArray, binary: NDArray[np.uint8], boxes: NDArray[np.int64]):
    """Area, shape and contrast of the pixels inside each thesis box (x0, y0, x1, y1 inclusive)."""
    h, w = binary.shape
    rows = []
    for (x0, y0, x1, y1) in boxes:
        mask = binary[y0:y1 + 1, x0:x1 + 1]
        m = cv2.moments(mask, binaryImage=True)
        roi = image[y0:y1 + 1, x0:x1 + 1]
        gx0, gy0, gx1, gy1 = max(x0 - RING, 0), max(y0 - RING, 0), min(x1 + RING, w - 1), min(y1 + RING, h - 1)
        big = image[gy0:gy1 + 1, gx0:gx1 + 1]
        ring = np.concatenate([big[0], big[-1], big[1:-1, 0], big[1:-1, -1]])
        peak = float(roi[mask > 0].max()) if np.any(mask) else float(roi.max())
        rows.append((max(m["m00"], 1e-300), m["mu20"], m["mu11"], m["mu02"], np.count_nonzero(mask),
                     peak - float(np.median(ring))))
    t = np.array(rows, float).reshape(-1, 6)
    ecc, axes, angle, cov = shape_from_moments(t[:, 0], t[:, 1], t[:, 2], t[:, 3], np.maximum(t[:, 4], 1))
    return t[:, 4], ecc, t[:, 5], cov, axes, angle


def detect_markers(image: ArrayLike, method: Method = "subpixel", *, threshold: float | None = None,
                   polarity: str = "bright", min_area: float = 3.0, max_area: float | None = None,
                   max_eccentricity: float = 1.0, reject_border: bool = True, ellipse: bool = False,
                   labeling: Labeling = "contours", weights_h: ArrayLike | None = None,
                   weights_v: ArrayLike | None = None) -> MarkerDetections:
    """Find circular markers in one image and return their centres with per-marker measures.

    Pixel convention: ``x`` right (column), ``y`` down (row), the centre of pixel
    ``image[row, col]`` at ``(col, row)`` — the convention of OpenCV's moments and projections.

    Parameters
    ----------
    image : (H, W) grey (uint8, uint16, float, bool) or (H, W, 3) BGR image; e.g. a 512 × 344 scanner
        frame of 0/255 pixels or a camera frame.
    method : ``"subpixel"`` (default, spec §1.2: intensity-weighted centroid of connected components)
        or ``"thesis"`` (spec §1.1: weighted-filter hill climbing on the binarised image, integer
        window positions + 0.5).
    threshold : grey level ``T`` of the given image; pixels ``> T`` (``< T`` for dark markers) belong
        to markers. ``None``: Otsu's threshold (the lower level on a binary frame).
    polarity : ``"bright"`` markers on a dark background, or ``"dark"``.
    min_area, max_area : px², accepted marker areas (pixel counts; ``subpixel`` only).
    max_eccentricity : reject blobs whose second-moment eccentricity exceeds it (``subpixel`` only).
    reject_border : drop components touching the image border (``subpixel`` only; ``thesis`` never
        searches within 8 px of the border).
    ellipse : ``subpixel`` only: centre of an ellipse fitted to sub-pixel edge points (at half
        contrast) instead of the weighted centroid. It is the centre of the imaged ellipse; the
        offset between it and the image of an oblique circle's centre needs the camera pose and is
        not corrected here.
    labeling : ``"contours"`` (default, fast) or ``"components"`` (``cv2.connectedComponentsWithStats``).
    weights_h, weights_v : ``thesis`` only: the 24 filter taps (default triangular 1…12,12…1, not
        the illegible thesis table).

    Returns
    -------
    MarkerDetections
        ``.xy`` (K, 2) px, ``.area``, ``.eccentricity``, ``.contrast`` (K,) and more, markers in
        raster order of their first pixel.

    Raises
    ------
    InvalidImage
        Not a 2-D image, empty, NaN pixels, unsupported type.
    InvalidDetectionParameter
        Unknown method, bad areas, eccentricity or weights.

    Examples
    --------
    >>> img = np.zeros((60, 80), np.uint8)
    >>> img[20:31, 30:41] = 255                  # an 11 × 11 block centred at (35, 25)
    >>> det = detect_markers(img)
    >>> det.xy.tolist(), det.area.tolist(), det.contrast.tolist()
    ([[35.0, 25.0]], [121.0], [255.0])
    >>> detect_markers(img, method="thesis").xy.tolist()   # odd width: a plateau, the climb stops early
    [[34.5, 24.5]]
    """
    if method not in METHODS:
        raise InvalidDetectionParameter(f"unknown method {method!r}; use one of {', '.join(METHODS)}")
    if labeling not in ("contours", "components"):
        raise InvalidDetectionParameter(f"labeling must be 'contours' or 'components', got {labeling!r}")
    max_area = np.inf if max_area is None else float(max_area)
    if not (0 <= min_area <= max_area):
        raise InvalidDetectionParameter(f"need 0 <= min_area <= max_area, got min_area={min_area}, "
                                        f"max_area={max_area} (px²)")
    if not (0.0 <= max_eccentricity <= 1.0):
        raise InvalidDetectionParameter(f"max_eccentricity must lie in [0, 1], got {max_eccentricity}")
    grey = grey_image(image)
    if threshold is not None and not np.isfinite(threshold):
        raise InvalidDetectionParameter(f"threshold must be a finite grey level, got {threshold}")
    if polarity not in ("bright", "dark"):
        raise InvalidDetectionParameter(f"polarity must be 'bright' or 'dark', got {polarity!r}")
    if polarity == "dark":
        level = inversion_level(grey)
        grey = level - grey
        threshold = None if threshold is None else level - threshold
    threshold = auto_threshold(grey) if threshold is None else float(threshold)
    binary = _binarise(grey, threshold)
    if method == "thesis":
        xy, boxes = thesis_centres(binary, weights_h, weights_v)
        if not len(xy):
            return MarkerDetections.empty("thesis", threshold)
        area, ecc, contrast, cov, axes, angle = _box_properties(grey, binary, boxes)
        return MarkerDetections(xy, area, ecc, contrast, cov, axes, angle, "thesis", threshold,
                                extra={"boxes": boxes})
    return subpixel_centroids(grey, binary, threshold, min_area=min_area, max_area=max_area,
                              max_eccentricity=max_eccentricity,
                              reject_border=reject_border, ellipse=ellipse, labeling=labeling)
