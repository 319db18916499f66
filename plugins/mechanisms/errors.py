"""Typed errors of the mechanism analysis.

Every error derives from :class:`MechanismError` (a :class:`mirrorlab.core.errors.AlgorithmError`)
and names the marker, group, frame or parameter concerned and what to do about it.
"""

from __future__ import annotations

from mirrorlab.core import AlgorithmError


class MechanismError(AlgorithmError):
    """Base class of the mechanism-analysis errors."""


class InvalidPoints(MechanismError, ValueError):
    """Marker or rod-end positions of the wrong shape, or too few finite samples."""


class GroupingError(MechanismError):
    """The markers do not split into the rigid groups a method needs (e.g. three moving links)."""


class DegenerateGeometry(MechanismError):
    """A pole, circle, joint or area is undefined for these positions (near-singular system)."""
