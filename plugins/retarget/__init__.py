"""Chain shape approximation (retargeting): map an n-DOF chain's motion onto an m-DOF chain.

Pure numpy functions after Toguro & Hashimoto, *Shape approximation using a multi-joint system*
(spec ``retargeting.md``). Units: mm (any consistent length unit), rad, s; right-handed frames.
"""

from .approximate import Approximation, InputChain, Tracker, approximate, input_chain, unwrap_to
from .chain import Chain, Tree, as_base, rotation
from .correspondence import correspondence_pairs, leaf_paths, normalised_positions, serial_correspondence
from .errors import (
    ChainDefinitionError,
    InputChainError,
    LengthDriftWarning,
    RetargetError,
    SourceError,
    TopologyError,
)
from .objective import Objective
from .solvers import levenberg_marquardt, multistart, paper_sweeps

__all__ = [name for name in dir() if not name.startswith("_") and name not in {"annotations"}]
