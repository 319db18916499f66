"""Typed errors of frame-to-frame tracking."""

from __future__ import annotations

from mirrorlab.core import AlgorithmError


class TrackingError(AlgorithmError):
    """Base class of tracking errors."""


class InvalidDetections(TrackingError, ValueError):
    """Detections have the wrong shape, or options are out of range."""
