"""Typed errors of marker detection.

Every error derives from :class:`MarkerError` (a :class:`mirrorlab.core.errors.AlgorithmError`),
names the frame or argument it concerns and says what to do about it.
"""

from __future__ import annotations

from mirrorlab.core import AlgorithmError


class MarkerError(AlgorithmError):
    """Base class of marker-detection errors."""


class InvalidImage(MarkerError, ValueError):
    """The image is not a 2-D grey (or 3-channel colour) array of a supported type, or is empty."""


class InvalidDetectionParameter(MarkerError, ValueError):
    """A detection parameter is out of range (threshold, areas, weights, method)."""
