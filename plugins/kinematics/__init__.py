"""Kinematics: filters, derivatives, rigid-body motion, RSSR model, joint angles, C3D/TRC import.

Pure functions (no plugin/CLI wiring). Units: mm, s, rad; right-handed world frame.
"""

from .derivatives import METHODS, derivatives
from .errors import (
    CannotAssemble,
    DegenerateAngularVelocity,
    DegenerateJointGeometry,
    DegenerateLinkage,
    DegenerateMarkerSet,
    GapTooLong,
    InsufficientSamples,
    KinematicsError,
    KinematicsIOError,
    NonMonotonicTime,
    NonMonotonicTimeSpline,
    NonUniformSampling,
    OutOfRange,
    ParallelBodyVectors,
    RSSRError,
    SingularFrame,
    ToggleSingularity,
    TruncatedMarkerFile,
)
from .filters import (
    THESIS_KERNEL,
    butterworth,
    fill_gaps,
    residual_cutoff,
    smoothing_spline,
    thesis_filter,
    thesis_filter_response,
)
from .io import MarkerData, read_c3d, read_qualisys_tsv, read_trc, write_c3d, write_csv
from .joint_angles import (
    UpperLimbAngles,
    elbow_flexion,
    isb_elbow_angles,
    isb_forearm_frame,
    isb_humerus_frame,
    isb_shoulder_angles,
    isb_thorax_frame,
    upper_limb_angles,
)
from .rigid import (
    RigidBodyMotion,
    angular_momentum,
    angular_velocity_two_vectors,
    body_frame,
    kabsch,
    omega_from_rotations,
    rigid_body_motion,
)
from .rssr import THESIS_RSSR, RSSRParams, RSSRState, rssr_angles_from_markers, rssr_state
from .thesis_spline import ParametricSpline, ThesisDerivatives, thesis_derivatives

__all__ = [name for name in dir() if not name.startswith("_") and name not in {"annotations"}]
