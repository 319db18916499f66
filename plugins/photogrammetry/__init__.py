"""Photogrammetry: camera models, calibration, parallel / central / mirror projection, error analysis."""

# --- mirror method (mirror.py, mirror_pose.py) ---
from .cameras import (  # noqa: E402
    CameraModel,
    ChessboardDetections,
    PinholeCamera,
    PlaneCalibration,
    calibrate_pinhole,
    chessboard_object_points,
    find_chessboard_corners,
    fit_plane_calibration,
)
from .central import (  # noqa: E402
    CentralCamera,
    CentralChainResult,
    film_to_perspective,
    object_image_distances,
    perspective_to_world,
    reconstruct_chain_central,
)

# --- end mirror method ---
# --- cameras, parallel / central projection, error analysis (cameras.py, parallel.py, central.py, sensitivity.py) ---
from .errors import (  # noqa: E402
    AmbiguousSign,
    CalibrationError,
    DegenerateGeometry,  # noqa: E402
    InconsistentLength,
    InvalidArgument,
    InvalidCamera,
    NoValidRoot,
    RayMissesSphere,
    RayNotForward,
)
from .mirror import (  # noqa: E402
    MirrorNormal,
    MirrorTriangulation,
    RayIntersection,
    VirtualCamera,
    intersect_rays,
    mirror_normal,
    reflect,
    reflection_matrix,
    triangulate_mirror,
    triangulate_mirrors,
    virtual_camera,
)
from .mirror_pose import (  # noqa: E402
    MirrorPose,
    TakahashiCalibration,
    calibrate_mirrors_takahashi,
    mirror_pose_from_views,
)
from .parallel import (  # noqa: E402
    ParallelChainResult,
    min_shooting_distance_rotation,
    min_shooting_distance_translation,
    reconstruct_chain_parallel,
    relative_image_error,
)
from .sensitivity import (  # noqa: E402
    THESIS_CENTRAL_ERRORS,
    THESIS_MIRROR_ERRORS,
    MirrorScene,
    SensitivityResult,
    accuracy_statistics,
    central_error_map,
    central_point_sensitivity,
    fit_table_angles,
    mirror_angle_sweep,
    mirror_error_map,
    mirror_point_sensitivity,
    monte_carlo,
    rotating_table_points,
    sphere_points,
    table_rotation,
)
# --- end cameras / parallel / central / sensitivity ---
