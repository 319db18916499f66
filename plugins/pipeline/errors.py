"""Typed errors of the demo pipeline glue."""

from __future__ import annotations

from mirrorlab.core import AlgorithmError


class PipelineError(AlgorithmError):
    """Base class of the pipeline glue's errors."""


class GridMatchError(PipelineError, ValueError):
    """The detected blobs could not be matched to the calibration grid (too few, no corner in view...)."""


class ViewSplitError(PipelineError, ValueError):
    """Detections cannot be split into direct and mirror images (bad shapes, mirror outline)."""


class EpipoleError(PipelineError, ValueError):
    """No mirror epipole is supported by the real/mirror detections."""


class SurveyError(PipelineError, ValueError):
    """A surveyed vector is malformed (wrong number of components, not a number)."""
