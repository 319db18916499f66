"""Typed errors of the kinematics algorithms.

Every error derives from :class:`KinematicsError` (itself a
:class:`mirrorlab.core.errors.AlgorithmError`), names the channel, marker, frame or angle it
concerns and says what to do about it.
"""

from __future__ import annotations

import numpy as np
from mirrorlab.core import AlgorithmError


class KinematicsError(AlgorithmError):
    """Base class of kinematics errors."""


class InsufficientSamples(KinematicsError):
    """Too few samples (or markers) for the requested filter, spline or fit."""


class NonUniformSampling(KinematicsError):
    """A method that needs uniform sampling (1-2-3-3-2-1 filter, Butterworth) got uneven times."""


class NonMonotonicTime(KinematicsError):
    """Sample times are not strictly increasing."""


class NonMonotonicTimeSpline(KinematicsError):
    """The time channel of the parametric spline is not monotonic on some segment (dt/du <= 0)."""


class OutOfRange(KinematicsError):
    """A query lies outside the sampled interval; splines do not extrapolate."""


class GapTooLong(KinematicsError):
    """A gap is longer than the allowed ``max_gap`` and may not be bridged."""


class DegenerateAngularVelocity(KinematicsError):
    """(3.51) is ill-conditioned: omega lies (nearly) in the plane of the two body vectors."""


class ParallelBodyVectors(KinematicsError):
    """The two body-fixed vectors are (nearly) parallel, so no body frame can be built."""


class DegenerateMarkerSet(KinematicsError):
    """A rigid-body fit is impossible: fewer than three visible non-collinear markers."""


class RSSRError(KinematicsError):
    """Base class of RSSR mechanism-model errors."""


class DegenerateLinkage(RSSRError):
    """The distance u = |d - a| vanishes (the crank tip coincides with the output pivot)."""


class CannotAssemble(RSSRError):
    """The linkage cannot close at this input angle (|c2| > 1 or negative discriminant)."""


class SingularFrame(RSSRError):
    """u is parallel to the output axis f, so the (lambda, mu, u) frame of (3.39) is undefined."""


class ToggleSingularity(RSSRError):
    """f . (c x b) = 0: the output velocity (3.42) and acceleration (3.43) are undefined."""


class DegenerateJointGeometry(KinematicsError):
    """A joint angle is undefined for this posture (e.g. fully extended elbow, collinear bar)."""


class KinematicsIOError(KinematicsError):
    """A marker file (C3D, TRC, TSV) is malformed or lacks the expected content."""


class TruncatedMarkerFile(KinematicsIOError):
    """A marker file was cut short: it holds less than its header declares or ends inside a record.

    Attributes
    ----------
    path : Path
        The file.
    declared : int
        Frames its header declares.
    found : int
        Complete frames present.
    """

    def __init__(self, path: object, declared: int, found: int, detail: str) -> None:
        self.path = path
        self.declared = declared
        self.found = found
        super().__init__(f"{path}: cut short: {detail}; copy the file again from its source "
                         "(an interrupted copy or download leaves such files)")


def first_index(mask: np.ndarray) -> tuple[int, ...]:
    """Index of the first True of ``mask`` as plain ints, for error messages (``()`` for a scalar)."""
    import numpy as np

    hits = np.argwhere(np.asarray(mask))
    return tuple(int(i) for i in hits[0]) if len(hits) else ()
