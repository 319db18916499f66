"""Typed errors of the photogrammetry algorithms; each names the frame/marker it concerns."""

from __future__ import annotations

from mirrorlab.core import AlgorithmError


class PhotogrammetryError(AlgorithmError):
    """Base class of photogrammetry errors."""


class CalibrationError(PhotogrammetryError):
    """A calibration fit is singular or under-determined (too few or collinear points)."""


class DegenerateGeometry(PhotogrammetryError):
    """Rays are parallel, a marker lies behind the camera, or a mirror normal is inconsistent."""


class AmbiguousSign(PhotogrammetryError):
    """The ± of a central/parallel-projection depth cannot be decided from the data."""


class InconsistentLength(PhotogrammetryError):
    """A link is shorter than its image implies (negative discriminant)."""


# --- subclasses used by cameras / parallel / central / sensitivity (part A) ---------------------


class InvalidArgument(PhotogrammetryError, ValueError):
    """A parameter is outside the range in which the thesis formula applies."""


class InvalidCamera(InvalidArgument):
    """Camera parameters admit no real solution (e.g. a < 4 f: no real focus)."""


class RayNotForward(DegenerateGeometry):
    """An image point maps to a ray that does not leave the camera forward."""


class RayMissesSphere(InconsistentLength):
    """The ray of a marker does not reach the sphere of its link length about the previous marker."""


class NoValidRoot(DegenerateGeometry):
    """Both ray-sphere intersections of a link lie behind the camera."""
