"""Mechanism analysis: rigid groups, linkage reconstruction, joints and swept areas (``analysis.md`` §3-§7)."""

from .errors import DegenerateGeometry, GroupingError, InvalidPoints, MechanismError
from .fourbar import LINK_NAMES, FourBar, reconstruct_four_bar, track_markers
from .grouping import RigidGroups, estimate_tolerance, rigid_groups, thesis_groups
from .joints import RevoluteJoint, SphericalJoint, revolute_joint, spherical_joint
from .swept import SpatialSweep, segment_swept_area, spatial_swept_area, strip_area, swept_region
from .walls import OptimalWall, arc_grid, astroid_motion, centrodes, eq63_motion, optimal_wall, wall_area, wall_motion
