"""Modern detector (spec analysis.md §1.2): sub-pixel intensity-weighted centroids of blobs.

Each 8-connected component of the binarised image ``I > T`` is one candidate marker. Its centre is
the background-subtracted intensity centroid :math:`\\bar x=\\sum x\\,(I-T)_+/\\sum (I-T)_+` over the
component (on a 0/255 binary frame this is the plain pixel centroid), or, with ``ellipse=True``, the
centre of an ellipse fitted (``cv2.fitEllipseDirect``) to sub-pixel edge points at half contrast
(half-way between the local background and the marker's peak).
Components are rejected by area, by second-moment eccentricity and (optionally) when they touch the
image border, where the centroid of a cut marker is biased.

Components come from ``cv2.findContours`` (``labeling="contours"``, the default: each outer contour
gives a component's bounding box, and where two boxes overlap the contours are filled to separate
the components; an order of magnitude faster than the alternative on this project's OpenCV build)
or from ``cv2.connectedComponentsWithStats`` (``labeling="components"``).
Both give identical results except for a component nested inside another one's hole, which the
contour labelling merges into the outer one.
"""

from __future__ import annotations

from typing import Literal

import cv2
import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from numpy.typing import NDArray

from .ellipse import edge_points, fit_ellipse
from .moments import shape_from_moments
from .result import MarkerDetections

Labeling = Literal["contours", "components"]
RING = 2  # px: the background ring is the border of the bounding box grown by this much
GROUP = 64  # blobs processed together (sorted by size, so padding stays small)


def _blobs(binary: NDArray[np.uint8], labeling: Labeling) -> tuple[NDArray[np.int64], list, NDArray | None]:
    """Bounding boxes (K, 4) ``x, y, w, h`` in raster order, with contours or the label image."""
    if labeling == "contours":
        contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        # raster order of the first (top-most, then left-most) pixel, like the thesis's search
        contours = sorted(contours, key=lambda c: (int(c[0, 0, 1]), int(c[0, 0, 0])))
        boxes = np.array([cv2.boundingRect(c) for c in contours], np.int64).reshape(-1, 4)
        return boxes, contours, None
    n, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8, ltype=cv2.CV_32S)
    return stats[1:, :4].astype(np.int64), list(range(1, n)), labels


def _box_overlaps(boxes: NDArray[np.int64]) -> NDArray[np.bool_]:
    """(K,) True where a bounding box intersects another one."""
    x, y, w, h = boxes.T
    hit = ((x[:, None] < (x + w)[None, :]) & (x[None, :] < (x + w)[:, None])
           & (y[:, None] < (y + h)[None, :]) & (y[None, :] < (y + h)[:, None]))
    np.fill_diagonal(hit, False)
    return hit.any(axis=1)


def _measure_group(image: NDArray, threshold: float, boxes: NDArray[np.int64], shapes: list,
                   labels: NDArray | None, ellipse: bool, overlaps: NDArray[np.bool_]) -> NDArray[np.float64]:
    """Moments and measures of blobs of similar size, vectorised over the group.

    Every blob gets a window of the group's common size (largest box grown by ``RING`` on each side),
    centred on its box, so the window's border is at least ``RING`` px from the blob: its median is
    the local background. Returns (K, 13): cx, cy, m00, mu20, mu11, mu02, area, contrast, and the
    ellipse's cx, cy, semi-axes and angle (NaN unless fitted).
    """
    k = len(boxes)
    x, y, w, h = boxes.T
    hm, wm = int(h.max()) + 2 * RING, int(w.max()) + 2 * RING
    wx0, wy0 = x - (wm - w) // 2, y - (hm - h) // 2  # window corners
    h_img, w_img = image.shape
    pad = 0
    if wx0.min() < 0 or wy0.min() < 0 or (wx0 + wm).max() > w_img or (wy0 + hm).max() > h_img:
        pad = max(hm, wm)  # windows leave the image: replicate the border
        image = cv2.copyMakeBorder(image, pad, pad, pad, pad, cv2.BORDER_REPLICATE)
        if labels is not None:
            labels = cv2.copyMakeBorder(labels, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
    grey = sliding_window_view(image, (hm, wm))[wy0 + pad, wx0 + pad].astype(np.float64)  # (K, hm, wm)
    if labels is None:
        # Pixels above the threshold inside a blob's own bounding box belong to it, unless another
        # box overlaps that box: only then is the blob's contour filled to separate them.
        bx, by = x - wx0, y - wy0
        cols, rows = np.arange(wm), np.arange(hm)
        in_box = (((rows >= by[:, None]) & (rows < (by + h)[:, None]))[:, :, None]
                  & ((cols >= bx[:, None]) & (cols < (bx + w)[:, None]))[:, None, :])
        mask = in_box & (grey > threshold)
        for i in np.flatnonzero(overlaps):
            fill = np.zeros((hm, wm), np.uint8)
            cv2.drawContours(fill, [shapes[i]], 0, 1, thickness=-1, offset=(-int(wx0[i]), -int(wy0[i])))
            mask[i] &= fill.view(bool)  # holes stay out: they are below the threshold
    else:
        mask = sliding_window_view(labels, (hm, wm))[wy0 + pad, wx0 + pad] == np.asarray(shapes)[:, None, None]
    wgt = np.where(mask, grey - threshold, 0.0)
    wy, wx = wgt.sum(2), wgt.sum(1)  # marginals (K, hm), (K, wm)
    m00 = wx.sum(1)
    rr, cc = np.arange(hm, dtype=np.float64), np.arange(wm, dtype=np.float64)
    lx = np.einsum("kc,c->k", wx, cc) / m00  # centroid in window coordinates (einsum: no BLAS threads)
    ly = np.einsum("kr,r->k", wy, rr) / m00
    dx, dy = cc - lx[:, None], rr - ly[:, None]
    out = np.full((k, 13), np.nan)
    out[:, 0], out[:, 1], out[:, 2] = wx0 + lx, wy0 + ly, m00
    out[:, 3] = np.einsum("kc,kc->k", wx, dx * dx)
    out[:, 4] = np.einsum("krc,kr,kc->k", wgt, dy, dx)
    out[:, 5] = np.einsum("kr,kr->k", wy, dy * dy)
    out[:, 6] = np.count_nonzero(mask.reshape(k, -1), axis=1)
    peak = np.where(mask, grey, -np.inf).reshape(k, -1).max(1)
    ring = np.concatenate([grey[:, 0, :], grey[:, -1, :], grey[:, 1:-1, 0], grey[:, 1:-1, -1]], axis=1)
    background = np.median(ring, axis=1)
    out[:, 7] = peak - background
    if ellipse:
        for i in range(k):
            fit = fit_ellipse(edge_points(grey[i], mask[i], background[i] + 0.5 * (peak[i] - background[i])))
            if fit is not None:
                (fx, fy), (a1, a2), ang = fit
                out[i, 8:] = wx0[i] + fx, wy0[i] + fy, a1, a2, ang
    return out


def _is_binary_frame(image: NDArray, binary: NDArray[np.uint8]) -> bool:
    """True for a 0/255 uint8 frame (the scanner's comparator output): it equals its binarisation."""
    return image.dtype == np.uint8 and cv2.countNonZero(cv2.compare(image, binary, cv2.CMP_NE)) == 0


def _measure_binary(binary: NDArray[np.uint8], boxes: NDArray[np.int64], shapes: list,
                    overlaps: NDArray[np.bool_], threshold: float) -> NDArray[np.float64]:
    """:func:`_measure_group`'s table for a 0/255 frame, from OpenCV's pixel moments of each blob.

    On a binary frame every marker pixel has the same weight ``255 - T``, so the weighted moments are
    the pixel moments times that weight, the peak is 255 and the background 0: one ``cv2.moments``
    call per blob replaces the window stack (about 3× faster on 512 × 344 scanner frames).
    """
    out = np.full((len(boxes), 13), np.nan)
    weight = 255.0 - threshold
    for i, (x, y, w, h) in enumerate(boxes):
        roi = binary[y:y + h, x:x + w]
        if overlaps[i]:  # another blob reaches into this box: keep only this blob's filled contour
            fill = np.zeros((h, w), np.uint8)
            cv2.drawContours(fill, [shapes[i]], 0, 255, thickness=-1, offset=(-int(x), -int(y)))
            roi = cv2.bitwise_and(roi, fill)
        m = cv2.moments(roi, binaryImage=True)
        n = m["m00"]
        if n > 0:
            out[i, :7] = (x + m["m10"] / n, y + m["m01"] / n, n * weight, m["mu20"] * weight,
                          m["mu11"] * weight, m["mu02"] * weight, n)
        else:
            out[i, :7] = (np.nan, np.nan, 0.0, 0.0, 0.0, 0.0, 0.0)
    out[:, 7] = 255.0
    return out


def subpixel_centroids(image: NDArray, binary: NDArray[np.uint8], threshold: float, *,
                       min_area: float = 3.0, max_area: float = np.inf, max_eccentricity: float = 1.0,
                       reject_border: bool = True, ellipse: bool = False,
                       labeling: Labeling = "contours") -> MarkerDetections:
    """Sub-pixel marker centres of a prepared image (see :func:`~mirrorlab.plugins.markers.detect_markers`).

    Parameters
    ----------
    image : (H, W) grey image (uint8, uint16 or float).
    binary : (H, W) uint8, 0 or 255: ``image > threshold``.
    threshold : grey level ``T`` of the weights ``(I - T)_+``.
    min_area, max_area : px², accepted component areas (pixel counts).
    max_eccentricity : reject blobs with a larger second-moment eccentricity (1 keeps all).
    reject_border : drop components touching the image border.
    ellipse : centre from an ellipse fitted to sub-pixel edge points instead of the centroid.
    labeling : ``"contours"`` or ``"components"`` (see the module notes).

    Returns
    -------
    MarkerDetections
        Markers in raster order of their first pixel.

    Notes
    -----
    The per-blob arithmetic is vectorised: blobs are gathered into a (K, h, w) stack (grouped by
    size) and their moments, areas, peaks and background medians computed in a few array
    operations; only the contour filling (and the optional ellipse fit) loops over blobs.
    """
    h_img, w_img = binary.shape
    boxes, shapes, labels = _blobs(binary, labeling)
    keep = boxes[:, 2] * boxes[:, 3] >= min_area
    if reject_border:
        x, y, w, h = boxes.T
        keep &= (x > 0) & (y > 0) & (x + w < w_img) & (y + h < h_img)
    idx = np.flatnonzero(keep)
    if not idx.size:
        return MarkerDetections.empty("subpixel", threshold)
    order = idx[np.argsort(boxes[idx, 2] * boxes[idx, 3], kind="stable")]
    overlaps = _box_overlaps(boxes) if labels is None else np.zeros(len(boxes), bool)
    table = np.empty((len(boxes), 13))
    if labels is None and not ellipse and _is_binary_frame(image, binary):
        table[idx] = _measure_binary(binary, boxes[idx], [shapes[i] for i in idx], overlaps[idx], threshold)
    else:
        for g in range(0, order.size, GROUP):
            sel = order[g:g + GROUP]
            table[sel] = _measure_group(image, threshold, boxes[sel], [shapes[i] for i in sel], labels, ellipse,
                                        overlaps[sel])
    t = table[idx]
    ecc, axes, angle, cov = shape_from_moments(t[:, 2], t[:, 3], t[:, 4], t[:, 5], t[:, 6])
    xy = t[:, :2]
    fitted = np.isfinite(t[:, 8])
    if ellipse:
        xy[fitted], axes[fitted], angle[fitted] = t[fitted, 8:10], t[fitted, 10:12], t[fitted, 12]
    ok = (t[:, 2] > 0) & (t[:, 6] >= min_area) & (t[:, 6] <= max_area) & (ecc <= max_eccentricity)
    return MarkerDetections(xy[ok], t[ok, 6], ecc[ok], t[ok, 7], cov[ok], axes[ok], angle[ok], "subpixel",
                            float(threshold), extra={"ellipse_fitted": fitted[ok] if ellipse else None})
