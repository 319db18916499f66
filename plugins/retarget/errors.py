"""Typed errors and warnings of chain retargeting.

Every error derives from :class:`RetargetError` (a :class:`mirrorlab.core.errors.AlgorithmError`)
and names the link, joint, frame or file it concerns and says what to do.
"""

from __future__ import annotations

from mirrorlab.core import AlgorithmError


class RetargetError(AlgorithmError):
    """Base class of retargeting errors."""


class ChainDefinitionError(RetargetError):
    """A chain or tree is ill-defined: bad axes string, non-positive length, bad parents or limits."""


class InputChainError(RetargetError):
    """The input joint positions cannot form a chain (wrong shape, zero-length arm, no valid frame)."""


class TopologyError(RetargetError):
    """Input and output topologies cannot be put in correspondence (leaf paths, branch points)."""


class SourceError(RetargetError):
    """A motion source (BVH, C3D, session marker set) is unreadable or lacks the named joints."""


class LengthDriftWarning(UserWarning):
    """An input arm's length deviates from its median by more than the tolerance in some frames."""
