"""Mirror pose from the scene: a calibration object photographed directly and/or through mirrors.

Two set-ups (spec §7, §9 "mirror orientation"; the thesis measures the normal from marker pairs,
these estimate the whole plane from a calibration object):

* :func:`mirror_pose_from_views` — intrinsics known; the object is seen **directly and in the
  mirror**. ``cv2.solvePnP`` on the direct view gives the camera; on the mirrored view (with mirrored
  object coordinates) the virtual camera; the mirror is the perpendicular bisector of the two
  centres, then refined jointly on both images' reprojection error.
* :func:`calibrate_mirrors_takahashi` — the object is seen **only through J ≥ 3 mirrors** (one photo
  per mirror pose): K. Takahashi, S. Nobuhara, T. Matsuyama, "A New Mirror-based Extrinsic Camera
  Calibration Using an Orthogonality Constraint", CVPR 2012. Closed form from the rotation axes of
  pairs of reflections (each mirror normal is the kernel of the axes it forms with the others),
  then nonlinear refinement with :func:`scipy.optimize.least_squares`.

Mirrored views show a left-handed copy of the object. A planar object (z = 0) maps to itself under
the mirrored coordinates ``diag(1, 1, -1)``, but a chessboard *detector* returns the corners of a
mirrored view in a flipped order: pass image points in the order of ``object_points``.

Units: mm, rad, pixels; right-handed frames. A plane is ``n·y + d = 0`` with the unit normal ``n``
toward the camera (reflecting side, eq. 3.10) and ``d > 0`` the camera-to-mirror distance in mm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial.transform import Rotation

from .errors import CalibrationError, DegenerateGeometry
from .mirror import reflect

__all__ = ["MirrorPose", "TakahashiCalibration", "mirror_pose_from_views", "calibrate_mirrors_takahashi"]

FloatArray = NDArray[np.float64]
_D = np.diag([1.0, 1.0, -1.0])  # mirrored object coordinates (a left-handed copy)


def _as_points(x: ArrayLike, dim: int, name: str) -> FloatArray:
    a = np.asarray(x, dtype=np.float64).reshape(-1, dim)
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{name} contains non-finite values")
    return a


def _dist(dist_coeffs: ArrayLike | None) -> FloatArray:
    d = np.zeros(5) if dist_coeffs is None else np.asarray(dist_coeffs, dtype=np.float64).ravel()
    return d


def _pnp(obj: FloatArray, img: FloatArray, K: FloatArray, dist: FloatArray, what: str) -> tuple[FloatArray, FloatArray]:
    if obj.shape[0] < 4:
        raise CalibrationError(f"{what}: PnP needs at least 4 points, got {obj.shape[0]}")
    ok, rvec, tvec = cv2.solvePnP(obj, img, K, dist, flags=cv2.SOLVEPNP_ITERATIVE)
    if not ok:
        raise CalibrationError(f"{what}: cv2.solvePnP failed; check the point order and the intrinsics")
    return cv2.Rodrigues(rvec)[0], tvec.ravel()


def _project(points_cam: FloatArray, K: FloatArray, dist: FloatArray) -> FloatArray:
    """Camera-frame points (N, 3) mm -> pixels (N, 2)."""
    zero = np.zeros(3)
    return cv2.projectPoints(points_cam.reshape(-1, 1, 3), zero, zero, K, dist)[0].reshape(-1, 2)


def _rms(residual: FloatArray) -> float:
    """RMS of the Euclidean pixel error of (..., 2) residuals."""
    r = residual.reshape(-1, 2)
    return float(np.sqrt(np.mean(np.sum(r * r, axis=1))))


# --------------------------------------------------------------------------- (a) direct + mirrored view


@dataclass(frozen=True)
class MirrorPose:
    """Camera and mirror in the calibration object's frame (the world frame).

    Attributes
    ----------
    normal : (3,) unit mirror normal toward the camera, world frame.
    mirror_point : (3,) mm, the foot of the perpendicular from the camera on the mirror (a G).
    distance : mm, camera-to-mirror distance.
    rotation, translation : world→camera, ``y = R x + t`` (R proper, t in mm).
    camera_center, virtual_center : (3,) mm, world frame (virtual = reflection of the camera).
    reprojection_rms : px, RMS over both views after refinement.
    reprojection_rms_real, reprojection_rms_virtual : px, per view.
    initial_rms : px, RMS of the closed-form (bisector) solution.
    """

    normal: FloatArray
    mirror_point: FloatArray
    distance: float
    rotation: FloatArray
    translation: FloatArray
    camera_center: FloatArray
    virtual_center: FloatArray
    reprojection_rms: float
    reprojection_rms_real: float
    reprojection_rms_virtual: float
    initial_rms: float


def mirror_pose_from_views(
    object_points: ArrayLike,
    image_points_real: ArrayLike,
    image_points_virtual: ArrayLike,
    camera_matrix: ArrayLike,
    dist_coeffs: ArrayLike | None = None,
    *,
    refine: bool = True,
) -> MirrorPose:
    """Mirror plane and camera pose from an object seen directly and in the mirror.

    Parameters
    ----------
    object_points : (P, 3) array_like, mm, in the object (world) frame.
    image_points_real : (P, 2) array_like, px, direct image, in ``object_points`` order.
    image_points_virtual : (P, 2) array_like, px, mirror image, in ``object_points`` order.
    camera_matrix : (3, 3) intrinsics K.
    dist_coeffs : OpenCV distortion coefficients, optional (none = undistorted points).
    refine : bool
        Refine camera pose and mirror plane jointly on both views' reprojection error.

    Returns
    -------
    MirrorPose
        ``camera_center``, ``mirror_point`` and ``normal`` feed :func:`triangulate_mirror`
        directly; world rays of pixels are ``rotation.T @ K⁻¹ [x, y, 1]``.

    Raises
    ------
    CalibrationError
        PnP fails or too few points.
    DegenerateGeometry
        The camera and virtual camera coincide (camera in the mirror plane).

    Examples
    --------
    >>> import numpy as np, cv2
    >>> K = np.array([[800., 0, 320], [0, 800., 240], [0, 0, 1]])
    >>> X = np.array([[x, y, 0.] for x in range(0, 200, 40) for y in range(0, 120, 40)])
    >>> R = cv2.Rodrigues(np.array([2.8, 0.2, 0.1]))[0]; t = np.array([-150., 40., 1200.])
    >>> C = -R.T @ t; n = np.array([0.9, 0, 0.436]); n /= np.linalg.norm(n); G = np.array([-250., 0, 0])
    >>> img = lambda P: cv2.projectPoints(P, cv2.Rodrigues(R)[0], t, K, None)[0].reshape(-1, 2)
    >>> pose = mirror_pose_from_views(X, img(X), img(reflect(X, G, n)), K)
    >>> np.allclose(pose.normal, n), bool(pose.reprojection_rms < 1e-6)
    (True, True)
    """
    X = _as_points(object_points, 3, "object_points")
    x1 = _as_points(image_points_real, 2, "image_points_real")
    x2 = _as_points(image_points_virtual, 2, "image_points_virtual")
    if not (X.shape[0] == x1.shape[0] == x2.shape[0]):
        raise ValueError("object_points and both image point arrays must have the same length")
    K = np.asarray(camera_matrix, dtype=np.float64)
    dist = _dist(dist_coeffs)
    R1, t1 = _pnp(X, x1, K, dist, "direct view")
    R2, t2 = _pnp(X @ _D, x2, K, dist, "mirrored view")  # virtual camera: y = R2 D x + t2
    C = -R1.T @ t1
    Cv = -_D @ R2.T @ t2
    baseline = C - Cv
    b = float(np.linalg.norm(baseline))
    if b < 1e-9 * max(1.0, float(np.linalg.norm(C))):
        raise DegenerateGeometry("camera and virtual camera coincide: the camera lies in the mirror plane")
    n0 = baseline / b
    G0 = 0.5 * (C + Cv)

    def residuals(p: FloatArray) -> FloatArray:
        rvec, tvec, nv, d = p[:3], p[3:6], p[6:9], p[9]
        nn = nv / np.linalg.norm(nv)
        both = np.concatenate([X, reflect(X, -d * nn, nn)])
        proj = cv2.projectPoints(both.reshape(-1, 1, 3), rvec, tvec, K, dist)[0].reshape(-1, 2)
        return (proj - np.concatenate([x1, x2])).ravel()

    p0 = np.concatenate([cv2.Rodrigues(R1)[0].ravel(), t1, n0, [-float(G0 @ n0)]])
    r0 = residuals(p0)
    p = least_squares(residuals, p0, method="lm").x if refine else p0
    r = residuals(p)
    R = cv2.Rodrigues(p[:3])[0]
    t = p[3:6]
    n = p[6:9] / np.linalg.norm(p[6:9])
    C = -R.T @ t
    G = -p[9] * n
    dist_cm = float((C - G) @ n)
    if dist_cm < 0:  # keep (3.10): normal toward the camera
        n, dist_cm = -n, -dist_cm
    G = C - dist_cm * n
    half = r.size // 2
    return MirrorPose(
        normal=n, mirror_point=G, distance=dist_cm, rotation=R, translation=t, camera_center=C,
        virtual_center=C - 2.0 * dist_cm * n, reprojection_rms=_rms(r),
        reprojection_rms_real=_rms(r[:half]), reprojection_rms_virtual=_rms(r[half:]), initial_rms=_rms(r0),
    )


# --------------------------------------------------------------------------- (b) Takahashi et al. 2012


@dataclass(frozen=True)
class TakahashiCalibration:
    """Object pose and J mirror planes in the **camera** frame (Takahashi et al. 2012).

    Attributes
    ----------
    rotation, translation : object→camera, ``y = R x + t`` (R proper, t in mm).
    normals : (J, 3) unit mirror normals toward the camera.
    distances : (J,) mm, camera-to-mirror distances ``d_j`` (plane ``n_j·y + d_j = 0``).
    mirror_points : (J, 3) mm, foot of the perpendicular from the camera, ``-d_j n_j``.
    dist_coeffs : (5,) OpenCV distortion coefficients used (refined k1, k2 if requested).
    reprojection_rms : px, RMS Euclidean error over all views after refinement.
    reprojection_mean : px, mean Euclidean error over all views after refinement.
    per_view_rms : (J,) px.
    linear_rms : px, RMS error of the closed-form solution.
    """

    rotation: FloatArray
    translation: FloatArray
    normals: FloatArray
    distances: FloatArray
    mirror_points: FloatArray
    dist_coeffs: FloatArray
    reprojection_rms: float
    reprojection_mean: float
    per_view_rms: FloatArray
    linear_rms: float


def _reflect_cam(Y: FloatArray, normals: FloatArray, dists: FloatArray) -> FloatArray:
    """Object points in the camera frame (P, 3) -> their images in each mirror (J, P, 3)."""
    s = Y @ normals.T + dists  # (P, J) signed distances
    return Y[None] - 2.0 * s.T[..., None] * normals[:, None, :]


def calibrate_mirrors_takahashi(
    object_points: ArrayLike,
    image_points: Sequence[ArrayLike],
    camera_matrix: ArrayLike,
    dist_coeffs: ArrayLike | None = None,
    *,
    refine: bool = True,
    refine_distortion: bool = False,
    min_angle: float = np.deg2rad(1.0),
) -> TakahashiCalibration:
    """Object pose and mirror planes from J ≥ 3 views of an object seen only through mirrors.

    1. ``cv2.solvePnP`` per view on the mirrored object coordinates gives :math:`R'_j` with
       :math:`R'_jD = A_jR` (:math:`A_j = I-2n_jn_j^T`, det −1), and :math:`T'_j = A_jT-2d_jn_j`.
    2. :math:`R'_jD(R'_kD)^T = A_jA_k` is a rotation about :math:`m_{jk}\\parallel n_j\\times n_k`;
       each :math:`n_j` spans the kernel of its axes :math:`\\{m_{jk}\\}_{k\\ne j}` (SVD).
    3. :math:`R` = chordal mean of :math:`A_jR'_jD`; :math:`T, d_j` by linear least squares on
       :math:`T'_j = A_jT-2d_jn_j`; signs so that :math:`d_j>0`.
    4. Refinement of :math:`R, T, n_j, d_j` (and optionally the radial distortion k1, k2, with K
       fixed) on the reprojection error with :func:`scipy.optimize.least_squares`.

    Parameters
    ----------
    object_points : (P, 3) array_like, mm.
    image_points : sequence of J (P, 2) array_like, px, each in ``object_points`` order.
    camera_matrix : (3, 3) intrinsics K (kept fixed).
    dist_coeffs : OpenCV distortion coefficients, optional.
    refine : bool
        Run the nonlinear refinement (step 4).
    refine_distortion : bool
        Also estimate k1, k2 (K fixed).
    min_angle : float, rad
        Minimum angle between two mirrors for their reflection pair to be used.

    Returns
    -------
    TakahashiCalibration

    Raises
    ------
    CalibrationError
        Fewer than three views, PnP failure.
    DegenerateGeometry
        A mirror is (nearly) parallel to all others, so its normal is undetermined.

    Examples
    --------
    >>> import numpy as np
    >>> K = np.array([[1000., 0, 500], [0, 1000., 400], [0, 0, 1]])
    >>> X = np.array([[x, y, 0.] for x in range(0, 200, 40) for y in range(0, 120, 40)])
    >>> R = np.diag([1., -1., -1.]); T = np.array([-100., -50., -300.])   # board faces away
    >>> ns = np.array([[0.1, 0.2, -1], [-0.3, 0.1, -1], [0.1, -0.35, -1]])
    >>> ns /= np.linalg.norm(ns, axis=1, keepdims=True); ds = np.array([600., 650., 700.])
    >>> Yv = _reflect_cam(X @ R.T + T, ns, ds)
    >>> img = [(y @ K.T)[:, :2] / (y @ K.T)[:, 2:] for y in Yv]
    >>> cal = calibrate_mirrors_takahashi(X, img, K)
    >>> np.allclose(cal.normals, ns, atol=1e-6), bool(cal.reprojection_rms < 1e-6)
    (True, True)
    """
    X = _as_points(object_points, 3, "object_points")
    xs = np.stack([_as_points(x, 2, f"image_points[{j}]") for j, x in enumerate(image_points)])
    J, P = xs.shape[0], X.shape[0]
    if J < 3:
        raise CalibrationError(f"Takahashi calibration needs at least 3 mirror poses, got {J}")
    if xs.shape[1] != P:
        raise ValueError(f"each image_points array must have {P} points (object_points), got {xs.shape[1]}")
    K = np.asarray(camera_matrix, dtype=np.float64)
    dist = _dist(dist_coeffs)

    poses = [_pnp(X @ _D, xs[j], K, dist, f"mirrored view {j}") for j in range(J)]
    RD = np.stack([R @ _D for R, _ in poses])  # A_j R (det -1)
    Tp = np.stack([t for _, t in poses])

    # Axes of A_j A_k for all pairs (vectorised), then each normal as the kernel of its axes.
    rel = np.einsum("jab,kcb->jkac", RD, RD)  # RD_j RD_k^T
    rv = Rotation.from_matrix(rel.reshape(-1, 3, 3)).as_rotvec().reshape(J, J, 3)
    ang = np.linalg.norm(rv, axis=2)  # = 2 x angle between mirrors j and k
    usable = ang > 2.0 * min_angle
    np.fill_diagonal(usable, False)
    axes = np.where(usable[..., None], rv / np.where(ang > 0, ang, 1.0)[..., None], 0.0)
    counts = usable.sum(axis=1)
    if np.any(counts < 2):
        bad = np.flatnonzero(counts < 2)
        raise DegenerateGeometry(
            f"mirror views {bad.tolist()}: fewer than two other mirrors differ by more than "
            f"{np.rad2deg(min_angle):.3g}°; tilt the mirror differently between photos"
        )
    normals = np.linalg.svd(axes)[2][:, -1, :]  # (J, 3) kernel of each view's axes
    A = np.eye(3)[None] - 2.0 * np.einsum("ja,jb->jab", normals, normals)
    Rc = np.einsum("jab,jbc->ac", A, RD)
    U, _, Vt = np.linalg.svd(Rc)
    R = U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt
    M = np.zeros((3 * J, 3 + J))
    M[:, :3] = A.reshape(3 * J, 3)
    M[np.arange(3 * J), 3 + np.repeat(np.arange(J), 3)] = -2.0 * normals.ravel()
    sol = np.linalg.lstsq(M, Tp.ravel(), rcond=None)[0]
    T, dists = sol[:3], sol[3:]
    sign = np.where(dists < 0, -1.0, 1.0)
    normals, dists = normals * sign[:, None], dists * sign

    n_dist = 2 if refine_distortion else 0

    def residuals(p: FloatArray) -> FloatArray:
        Rm = Rotation.from_rotvec(p[:3]).as_matrix()
        nv = p[6:6 + 3 * J].reshape(J, 3)
        nn = nv / np.linalg.norm(nv, axis=1, keepdims=True)
        dd = dist.copy()
        if n_dist:
            dd[:2] = p[6 + 4 * J:]
        Yv = _reflect_cam(X @ Rm.T + p[3:6], nn, p[6 + 3 * J:6 + 4 * J])
        return (_project(Yv.reshape(-1, 3), K, dd).reshape(J, P, 2) - xs).ravel()

    p0 = np.concatenate([Rotation.from_matrix(R).as_rotvec(), T, normals.ravel(), dists, dist[:n_dist]])
    linear_rms = _rms(residuals(p0))
    p = least_squares(residuals, p0, method="trf", x_scale="jac", xtol=1e-12, ftol=1e-12).x if refine else p0
    r = residuals(p).reshape(J, P, 2)
    nv = p[6:6 + 3 * J].reshape(J, 3)
    normals = nv / np.linalg.norm(nv, axis=1, keepdims=True)
    dists = p[6 + 3 * J:6 + 4 * J]
    dist_out = dist.copy()
    if n_dist:
        dist_out[:2] = p[6 + 4 * J:]
    err = np.linalg.norm(r, axis=2)
    return TakahashiCalibration(
        rotation=Rotation.from_rotvec(p[:3]).as_matrix(), translation=p[3:6], normals=normals,
        distances=dists, mirror_points=-dists[:, None] * normals, dist_coeffs=dist_out,
        reprojection_rms=_rms(r), reprojection_mean=float(err.mean()),
        per_view_rms=np.sqrt(np.mean(err**2, axis=1)), linear_rms=linear_rms,
    )
