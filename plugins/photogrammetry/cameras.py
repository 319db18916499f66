"""Camera models: a common interface, the thesis plane calibration (§3.2.3) and an OpenCV pinhole model.

Every model gives the camera centre (mm, world frame) and unit world rays for image points; the world
frame is right-handed and, for the plane calibration, the calibration plane is ``Z = plane_z``.

* :func:`fit_plane_calibration` — thesis eqs 3.15–3.20 (second-order polynomial image -> plane map),
  or ``model="projective"`` (homography + optional radial terms, exact for a pinhole at any tilt).
* :func:`calibrate_pinhole` — Zhang's method via :func:`cv2.calibrateCamera`.
* :func:`find_chessboard_corners` — chessboard corner detection in image files.
"""

from __future__ import annotations

import os
from collections.abc import Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal, Protocol, runtime_checkable

import cv2
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares
from scipy.spatial import Delaunay

from .errors import CalibrationError, DegenerateGeometry, InvalidArgument

__all__ = [
    "CameraModel",
    "PlaneCalibration",
    "fit_plane_calibration",
    "quadratic_design_matrix",
    "PinholeCamera",
    "calibrate_pinhole",
    "ChessboardDetections",
    "find_chessboard_corners",
    "chessboard_object_points",
]


@runtime_checkable
class CameraModel(Protocol):
    """Interface of every calibrated camera: centre (3,) mm and unit world rays for image points."""

    @property
    def camera_center(self) -> NDArray[np.float64]:
        """Object-space projection centre (mm, world frame)."""

    def rays(self, image_xy: ArrayLike) -> NDArray[np.float64]:
        """Unit world directions (N, 3) from the camera centre through image points (N, 2)."""

    def project(self, points: ArrayLike) -> NDArray[np.float64]:
        """Image coordinates (N, 2) of world points (N, 3)."""


def quadratic_design_matrix(image_xy: ArrayLike) -> NDArray[np.float64]:
    """Rows ``[1, x, y, xy, x^2, y^2]`` of eqs 3.15–3.16 for image points (N, 2).

    Examples
    --------
    >>> quadratic_design_matrix([[2.0, 3.0]]).tolist()
    [[1.0, 2.0, 3.0, 6.0, 4.0, 9.0]]
    """
    xy = np.asarray(image_xy, dtype=float)
    x, y = xy[..., 0], xy[..., 1]
    return np.stack([np.ones_like(x), x, y, x * y, x * x, y * y], axis=-1)


def _scaled_to_raw(center: NDArray, scale: float) -> NDArray:
    """T with phi(u, v) = T phi(x, y), u = (x - mx)/s, v = (y - my)/s."""
    mx, my = center
    s = scale
    return np.array([
        [1, 0, 0, 0, 0, 0],
        [-mx / s, 1 / s, 0, 0, 0, 0],
        [-my / s, 0, 1 / s, 0, 0, 0],
        [mx * my / s**2, -my / s**2, -mx / s**2, 1 / s**2, 0, 0],
        [mx**2 / s**2, -2 * mx / s**2, 0, 0, 1 / s**2, 0],
        [my**2 / s**2, 0, -2 * my / s**2, 0, 0, 1 / s**2],
    ])


@dataclass(frozen=True)
class PlaneCalibration:
    """Calibrated image -> calibration-plane map with its camera centre (thesis §3.2.3, eq. 3.20).

    Attributes
    ----------
    model : {"quadratic", "projective"}
    plane_z : float
        Z of the calibration plane (mm).
    camera_center : ndarray (3,)
        Object-space principal point F1 (mm).
    params : ndarray
        Quadratic: (6, 2) coefficients on normalised image coordinates; projective: 8 homography
        entries (H[2, 2] = 1) followed by the radial coefficients.
    center, scale : ndarray (2,), float
        Image normalisation ``u = (xy - center) / scale`` (image units).
    residuals : ndarray (N, 2)
        Mapped minus true calibration-plane coordinates (mm).
    rms, max_residual : float
        RMS and largest Euclidean residual (mm).
    condition : float
        Condition number of the normalised design matrix (quadratic) or of the Jacobian (projective).
    image_xy : ndarray (N, 2)
        The calibration image points (for the ``extrapolated`` test).
    """

    model: str
    plane_z: float
    camera_center: NDArray[np.float64]
    params: NDArray[np.float64]
    center: NDArray[np.float64]
    scale: float
    residuals: NDArray[np.float64]
    rms: float
    max_residual: float
    condition: float
    image_xy: NDArray[np.float64] = field(repr=False)
    n_radial: int = 0

    # ---- thesis coefficients ------------------------------------------------------------------
    @property
    def thesis_coefficients(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(b, c)``: b1..b6, c1..c6 of eqs 3.15–3.16 in raw image units (quadratic model only)."""
        if self.model != "quadratic":
            raise InvalidArgument("thesis_coefficients exist only for model='quadratic'")
        T = _scaled_to_raw(self.center, self.scale)
        bc = T.T @ self.params
        return bc[:, 0], bc[:, 1]

    # ---- forward map ----------------------------------------------------------------------------
    def _normalise(self, image_xy: ArrayLike) -> NDArray:
        return (np.asarray(image_xy, dtype=float) - self.center) / self.scale

    def _undistort_n(self, u: NDArray) -> NDArray:
        k = self.params[8:]
        if k.size == 0:
            return u
        r2 = np.sum(u * u, axis=-1, keepdims=True)
        return u * (1 + np.sum(k * r2 ** np.arange(1, k.size + 1), axis=-1, keepdims=True))

    def map_to_plane(self, image_xy: ArrayLike) -> NDArray[np.float64]:
        """Calibration-plane coordinates (X̄, Ȳ) in mm of image points (..., 2) (eqs 3.15–3.16)."""
        u = self._normalise(image_xy)
        if self.model == "quadratic":
            return quadratic_design_matrix(u) @ self.params
        H = np.append(self.params[:8], 1.0).reshape(3, 3)
        uu = self._undistort_n(u)
        h = np.concatenate([uu, np.ones(uu.shape[:-1] + (1,))], axis=-1) @ H.T
        return h[..., :2] / h[..., 2:3]

    def rays(self, image_xy: ArrayLike) -> NDArray[np.float64]:
        """Unit world rays ``(C - F1)/|C - F1|`` with ``C = (X̄, Ȳ, Z_c)`` (eq. 3.20), shape (..., 3).

        Examples
        --------
        >>> g = np.mgrid[-2:3, -2:3].reshape(2, -1).T * 100.0
        >>> cal = fit_plane_calibration(g / 10, g, 0.0, [0, 0, 1000.0])
        >>> np.round(cal.rays([[0.0, 0.0]]), 12) + 0.0
        array([[ 0.,  0., -1.]])
        """
        XY = self.map_to_plane(image_xy)
        C = np.concatenate([XY, np.full(XY.shape[:-1] + (1,), self.plane_z)], axis=-1)
        d = C - self.camera_center
        return d / np.linalg.norm(d, axis=-1, keepdims=True)

    def extrapolated(self, image_xy: ArrayLike) -> NDArray[np.bool_]:
        """True where an image point lies outside the convex hull of the calibration image points."""
        xy = np.asarray(image_xy, dtype=float)
        return Delaunay(self.image_xy).find_simplex(xy.reshape(-1, 2)).reshape(xy.shape[:-1]) < 0

    # ---- inverse map ----------------------------------------------------------------------------
    def plane_to_image(self, plane_xy: ArrayLike, iterations: int = 30) -> NDArray[np.float64]:
        """Invert :meth:`map_to_plane` (vectorised Newton for the quadratic/radial parts)."""
        P = np.asarray(plane_xy, dtype=float)
        if self.model == "quadratic":
            B = self.params
            A = B[1:3].T  # affine part, d(X,Y)/d(u,v) at u = v = 0
            u = np.linalg.solve(A, (P - B[0]).reshape(-1, 2).T).T.reshape(P.shape)
            for _ in range(iterations):
                r = quadratic_design_matrix(u) @ B - P
                uu, vv = u[..., 0:1], u[..., 1:2]
                dphi_du = np.concatenate([0 * uu, 1 + 0 * uu, 0 * uu, vv, 2 * uu, 0 * uu], axis=-1)
                dphi_dv = np.concatenate([0 * uu, 0 * uu, 1 + 0 * uu, uu, 0 * uu, 2 * vv], axis=-1)
                J = np.stack([dphi_du @ B, dphi_dv @ B], axis=-1)  # (..., 2 out, 2 in)
                u = u - np.linalg.solve(J, r[..., None])[..., 0]
            return u * self.scale + self.center
        H = np.append(self.params[:8], 1.0).reshape(3, 3)
        h = np.concatenate([P, np.ones(P.shape[:-1] + (1,))], axis=-1) @ np.linalg.inv(H).T
        uu = h[..., :2] / h[..., 2:3]
        k = self.params[8:]
        if k.size:
            ru = np.linalg.norm(uu, axis=-1)
            rd = ru.copy()
            pw = np.arange(1, k.size + 1)
            for _ in range(iterations):  # solve rd (1 + sum k rd^2j) = ru
                g = rd * (1 + np.sum(k * rd[..., None] ** (2 * pw), axis=-1)) - ru
                dg = 1 + np.sum(k * (2 * pw + 1) * rd[..., None] ** (2 * pw), axis=-1)
                rd = rd - g / dg
            with np.errstate(invalid="ignore", divide="ignore"):
                fac = np.where(ru > 0, rd / ru, 1.0)
            uu = uu * fac[..., None]
        return uu * self.scale + self.center

    def project(self, points: ArrayLike) -> NDArray[np.float64]:
        """Image coordinates of world points (..., 3): the ray F1 -> P meets the plane at C, then inverse map."""
        P = np.asarray(points, dtype=float)
        F = self.camera_center
        t = (self.plane_z - F[2]) / (P[..., 2] - F[2])
        C = F + t[..., None] * (P - F)
        return self.plane_to_image(C[..., :2])


def fit_plane_calibration(
    image_xy: ArrayLike,
    plane_xy: ArrayLike,
    plane_z: float,
    camera_center: ArrayLike,
    model: Literal["quadratic", "projective"] = "quadratic",
    solver: Literal["lstsq", "normal_equations"] = "lstsq",
    radial_terms: int = 0,
    distortion_center: ArrayLike | None = None,
    max_condition: float = 1e10,
    tol_plane: float = 1e-6,
) -> PlaneCalibration:
    """Fit the image -> calibration-plane map of the thesis (eqs 3.15–3.19) or a homography.

    Parameters
    ----------
    image_xy : array_like, shape (N, 2)
        Image coordinates of the calibration points (any consistent unit: film mm, pixels, counts).
    plane_xy : array_like, shape (N, 2)
        Their (X, Y) on the calibration plane (mm).
    plane_z : float
        Z of the calibration plane (mm).
    camera_center : array_like, shape (3,)
        Object-space principal point F1 (mm); must not lie on the calibration plane.
    model : {"quadratic", "projective"}
        ``"quadratic"`` (thesis, default): second-order polynomial; exact only for a film plane
        parallel to the calibration plane. ``"projective"``: homography (cv2.findHomography) plus
        ``radial_terms`` radial coefficients about ``distortion_center`` (default: the centroid of
        the image points), refined by scipy.optimize.least_squares; exact for a pinhole at any tilt.
    solver : {"lstsq", "normal_equations"}
        Quadratic only: QR least squares on centred/scaled coordinates (default) or the thesis's
        normal equations (3.19) (same solution, worse conditioning).
    radial_terms : int
        Number of radial terms k1, k2, ... of the projective model.
    distortion_center : array_like (2,), optional
        Centre of the radial terms (image units).
    max_condition : float
        Largest accepted condition number of the normalised design matrix.
    tol_plane : float
        Smallest accepted |F1_z - plane_z| (mm).

    Returns
    -------
    PlaneCalibration
        With per-point residuals, RMS (mm) and condition number.

    Raises
    ------
    CalibrationError
        Too few points (the message says how many there are and how many are needed), collinear or
        conic-degenerate point sets, or an ill-conditioned fit.
    DegenerateGeometry
        The camera centre lies on the calibration plane.

    Examples
    --------
    >>> g = np.mgrid[-3:4, -2:3].reshape(2, -1).T * 100.0          # plane grid, mm
    >>> img = 30.0 * g / 1442.0                                     # parallel pinhole, f = 30 mm
    >>> cal = fit_plane_calibration(img, g, 0.0, [0.0, 0.0, 1442.0])
    >>> cal.rms < 1e-9
    True
    """
    xy = np.asarray(image_xy, dtype=float)
    XY = np.asarray(plane_xy, dtype=float)
    F = np.asarray(camera_center, dtype=float).reshape(3)
    if xy.ndim != 2 or xy.shape[1] != 2 or XY.shape != xy.shape:
        raise InvalidArgument(f"image_xy and plane_xy must both have shape (N, 2); got {xy.shape} and {XY.shape}")
    if abs(F[2] - plane_z) <= tol_plane:
        raise DegenerateGeometry(
            f"camera centre Z = {F[2]} mm lies on the calibration plane Z = {plane_z} mm; rays through "
            "the plane are undefined. Re-measure F1 or use a calibration plane away from the camera"
        )
    n = len(xy)
    ok = np.all(np.isfinite(xy), axis=1) & np.all(np.isfinite(XY), axis=1)
    if not ok.all():
        raise CalibrationError(f"calibration points {np.flatnonzero(~ok).tolist()} contain NaN/inf; remove them")
    center = xy.mean(axis=0) if distortion_center is None else np.asarray(distortion_center, float)
    scale = float(np.sqrt(np.mean(np.sum((xy - xy.mean(axis=0)) ** 2, axis=1)))) or 1.0
    u = (xy - center) / scale

    if model == "quadratic":
        if n < 6:
            raise CalibrationError(
                f"only {n} calibration point{'s' * (n != 1)}; the quadratic map (eqs 3.15-3.16) has 6 unknowns per axis "
                "and needs at least 6 points (better: a grid of >= 9 spread over the field); digitise more points"
            )
        Phi = quadratic_design_matrix(u)
        sv = np.linalg.svd(Phi, compute_uv=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
        rank = int(np.sum(sv > sv[0] * 1e-12))
        if rank < 6 or cond > max_condition:
            raise CalibrationError(
                f"the {n} calibration points give a singular quadratic fit (rank {rank} < 6 or condition "
                f"{cond:.3g} > {max_condition:.0e}): they are collinear or lie on one conic; "
                "use points spread over the whole field in at least three rows and columns"
            )
        if solver == "lstsq":
            params = np.linalg.lstsq(Phi, XY, rcond=None)[0]
        elif solver == "normal_equations":
            Praw = quadratic_design_matrix(xy)
            N = Praw.T @ Praw  # (3.19), thesis form in raw coordinates
            piv = np.abs(np.diag(np.linalg.cholesky(N))) if np.all(np.linalg.eigvalsh(N) > 0) else np.zeros(1)
            if np.min(piv) <= 1e-10:
                raise CalibrationError(
                    f"normal equations (3.19) of the {n} points have a pivot <= 1e-10; the points are "
                    "degenerate or badly scaled: use solver='lstsq' or better-spread points"
                )
            b = np.linalg.solve(N, Praw.T @ XY)
            params = np.linalg.solve(_scaled_to_raw(center, scale).T, b)
        else:
            raise InvalidArgument(f"solver must be 'lstsq' or 'normal_equations', not {solver!r}")
        residuals = Phi @ params - XY
        n_radial = 0
    elif model == "projective":
        need = 4 + (radial_terms + 1) // 2
        if n < need:
            raise CalibrationError(
                f"only {n} calibration point{'s' * (n != 1)}; a homography with {radial_terms} radial terms needs at "
                f"least {need}; digitise more points"
            )
        if np.linalg.matrix_rank(np.c_[u, np.ones(n)], tol=1e-9) < 3:
            raise CalibrationError(
                f"the {n} calibration image points are collinear; a homography needs points spread in two "
                "directions"
            )
        H0, _ = cv2.findHomography(u, XY, 0)
        if H0 is None or abs(H0[2, 2]) < 1e-15:
            raise CalibrationError(f"cv2.findHomography failed on the {n} points; check for duplicates or collinearity")
        x0 = np.concatenate([(H0 / H0[2, 2]).ravel()[:8], np.zeros(radial_terms)])

        def model_xy(p: NDArray) -> NDArray:
            H = np.append(p[:8], 1.0).reshape(3, 3)
            k = p[8:]
            uu = u
            if k.size:
                r2 = np.sum(u * u, axis=1, keepdims=True)
                uu = u * (1 + np.sum(k * r2 ** np.arange(1, k.size + 1), axis=1, keepdims=True))
            h = np.c_[uu, np.ones(n)] @ H.T
            return h[:, :2] / h[:, 2:3]

        sol = least_squares(lambda p: (model_xy(p) - XY).ravel(), x0, method="lm", xtol=1e-15, ftol=1e-15, gtol=1e-15)
        params = sol.x
        sv = np.linalg.svd(sol.jac, compute_uv=False)
        cond = float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf
        if not np.isfinite(cond) or cond > max_condition:
            raise CalibrationError(
                f"the projective fit of the {n} points is ill-conditioned (condition {cond:.3g}); "
                "use fewer radial terms or points covering more of the image"
            )
        residuals = model_xy(params) - XY
        n_radial = radial_terms
    else:
        raise InvalidArgument(f"model must be 'quadratic' or 'projective', not {model!r}")
    err = np.linalg.norm(residuals, axis=1)
    return PlaneCalibration(
        model=model, plane_z=float(plane_z), camera_center=F, params=params, center=center, scale=scale,
        residuals=residuals, rms=float(np.sqrt(np.mean(err**2))), max_residual=float(err.max()),
        condition=cond, image_xy=xy, n_radial=n_radial,
    )


# ------------------------------------------------------------------------------------------------
# OpenCV pinhole + distortion (Zhang)
# ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PinholeCamera:
    """Pinhole camera with OpenCV lens distortion.

    Attributes
    ----------
    K : ndarray (3, 3)
        Intrinsic matrix (pixels).
    dist : ndarray
        OpenCV distortion coefficients (k1, k2, p1, p2, k3, ...).
    R : ndarray (3, 3)
        World -> camera rotation.
    t : ndarray (3,)
        World -> camera translation (mm if the object points are in mm).
    image_size : tuple (width, height) or None
    rms : float or None
        RMS reprojection error of the calibration (pixels).
    views : tuple of (R, t)
        Extrinsics of every calibration view.
    per_view_rms : ndarray or None
        RMS reprojection error per view (pixels).

    Examples
    --------
    >>> cam = PinholeCamera(np.array([[1000., 0, 320], [0, 1000., 240], [0, 0, 1]]), np.zeros(5),
    ...                     np.eye(3), np.array([0., 0., 0.]))
    >>> cam.project([[0.0, 0.0, 1000.0]]).tolist()
    [[320.0, 240.0]]
    >>> np.round(cam.rays([[320.0, 240.0]]), 12).tolist()
    [[0.0, 0.0, 1.0]]
    """

    K: NDArray[np.float64]
    dist: NDArray[np.float64]
    R: NDArray[np.float64]
    t: NDArray[np.float64]
    image_size: tuple[int, int] | None = None
    rms: float | None = None
    views: tuple = ()
    per_view_rms: NDArray[np.float64] | None = None

    @property
    def camera_center(self) -> NDArray[np.float64]:
        """Camera centre ``-R^T t`` in world coordinates."""
        return -self.R.T @ np.asarray(self.t, float).reshape(3)

    @property
    def rvec(self) -> NDArray[np.float64]:
        """Rodrigues vector of R."""
        return cv2.Rodrigues(np.asarray(self.R, float))[0].ravel()

    def normalized(self, image_xy: ArrayLike) -> NDArray[np.float64]:
        """Undistorted normalised image coordinates (N, 2) via cv2.undistortPoints."""
        xy = np.asarray(image_xy, dtype=np.float64).reshape(-1, 1, 2)
        if not len(xy):  # cv2.undistortPoints returns None for no points
            return np.empty((0, 2))
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-14)
        return cv2.undistortPoints(xy, self.K, self.dist, None, None, None, crit).reshape(-1, 2)

    def rays(self, image_xy: ArrayLike) -> NDArray[np.float64]:
        """Unit world rays (N, 3) through image points (N, 2) (pixels)."""
        n = self.normalized(image_xy)
        d = np.c_[n, np.ones(len(n))] @ np.asarray(self.R, float)  # R^T d_cam, row-wise
        return d / np.linalg.norm(d, axis=1, keepdims=True)

    def project(self, points: ArrayLike) -> NDArray[np.float64]:
        """Pixel coordinates (N, 2) of world points (N, 3) via cv2.projectPoints."""
        P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        # camera frame first: cv2.Rodrigues(R) loses precision for rotations near identity
        Pc = P @ np.asarray(self.R, float).T + np.asarray(self.t, float).reshape(3)
        img, _ = cv2.projectPoints(Pc, np.zeros(3), np.zeros(3), self.K, self.dist)
        return img.reshape(-1, 2)

    def view(self, index: int) -> PinholeCamera:
        """The same intrinsics with the extrinsics of calibration view ``index``."""
        R, t = self.views[index]
        return PinholeCamera(self.K, self.dist, R, t, self.image_size, self.rms, self.views, self.per_view_rms)


def calibrate_pinhole(
    object_points_list: Sequence[ArrayLike],
    image_points_list: Sequence[ArrayLike],
    image_size: tuple[int, int],
    fix_aspect_ratio: bool = False,
    flags: int = 0,
    reference_view: int = 0,
    K_guess: ArrayLike | None = None,
) -> PinholeCamera:
    """Zhang calibration of a pinhole + distortion camera with :func:`cv2.calibrateCamera`.

    Parameters
    ----------
    object_points_list : sequence of array_like (M_v, 3)
        Planar target points per view (mm; Z = 0 for a planar board).
    image_points_list : sequence of array_like (M_v, 2)
        Detected image points per view (pixels).
    image_size : (width, height)
        Image size in pixels.
    fix_aspect_ratio : bool
        Add ``cv2.CALIB_FIX_ASPECT_RATIO`` (fx = fy; needs an initial K, taken from ``K_guess`` or
        an identity-aspect guess).
    flags : int
        Further OpenCV calibration flags.
    reference_view : int
        View whose extrinsics become the camera's world frame (the target frame of that view).
    K_guess : array_like (3, 3), optional
        Initial intrinsics (used with ``fix_aspect_ratio`` or ``cv2.CALIB_USE_INTRINSIC_GUESS``).

    Returns
    -------
    PinholeCamera
        With ``rms`` (pixels), ``per_view_rms`` and every view's extrinsics in ``views``.

    Raises
    ------
    CalibrationError
        Fewer than 3 views, a view with fewer than 6 points, mismatched lists, or an OpenCV failure.

    Examples
    --------
    >>> K = np.array([[800., 0, 320], [0, 800., 240], [0, 0, 1]])
    >>> obj = chessboard_object_points((6, 5), 30.0)
    >>> views = [(np.array([0.3, 0.0, 0.0]), np.array([-80., -60., 600.])),
    ...          (np.array([0.0, 0.4, 0.1]), np.array([-60., -70., 650.])),
    ...          (np.array([-0.3, -0.2, 0.0]), np.array([-70., -50., 550.]))]
    >>> img = [cv2.projectPoints(obj, r, t, K, None)[0].reshape(-1, 2) for r, t in views]
    >>> cam = calibrate_pinhole([obj] * 3, img, (640, 480))
    >>> bool(cam.rms < 1e-3), bool(abs(cam.K[0, 0] - 800) < 1e-2)
    (True, True)
    """
    if len(object_points_list) != len(image_points_list):
        raise CalibrationError(
            f"{len(object_points_list)} object-point sets but {len(image_points_list)} image-point sets; "
            "pass one of each per view"
        )
    nv = len(object_points_list)
    if nv < 3:
        raise CalibrationError(f"only {nv} view{'s' * (nv != 1)}; Zhang calibration needs at least 3 views of the board "
                               "in different orientations")
    obj, img = [], []
    for v, (o, i) in enumerate(zip(object_points_list, image_points_list)):
        o = np.asarray(o, dtype=np.float32).reshape(-1, 3)
        i = np.asarray(i, dtype=np.float32).reshape(-1, 2)
        if len(o) != len(i) or len(o) < 6:
            raise CalibrationError(
                f"view {v}: {len(o)} object points and {len(i)} image points; each view needs the same "
                "number, at least 6; drop or re-detect this view"
            )
        obj.append(o)
        img.append(i)
    w, h = image_size
    if fix_aspect_ratio:
        flags |= cv2.CALIB_FIX_ASPECT_RATIO
    K0 = np.asarray(K_guess, float) if K_guess is not None else np.array(
        [[max(w, h), 0, w / 2], [0, max(w, h), h / 2], [0, 0, 1]], float)
    try:
        rms, K, dist, rvecs, tvecs, _, _, per_view = cv2.calibrateCameraExtended(
            obj, img, (int(w), int(h)), K0.copy(), None, flags=flags
        )
    except cv2.error as exc:
        raise CalibrationError(f"cv2.calibrateCamera failed on {nv} views: {exc}; check the detections") from None
    if not np.isfinite(rms) or not np.all(np.isfinite(K)):
        raise CalibrationError(f"calibration of {nv} views diverged; check the board size and detections")
    views = tuple((cv2.Rodrigues(r)[0], np.asarray(t, float).reshape(3)) for r, t in zip(rvecs, tvecs))
    R, t = views[reference_view]
    return PinholeCamera(K, dist.ravel(), R, t, (int(w), int(h)), float(rms), views, per_view.ravel())


# ------------------------------------------------------------------------------------------------
# Chessboard detection
# ------------------------------------------------------------------------------------------------


def chessboard_object_points(pattern_size: tuple[int, int], square_size: float = 1.0) -> NDArray[np.float32]:
    """Board corners (cols*rows, 3) on Z = 0 in OpenCV's detection order (x fastest), in square units.

    Examples
    --------
    >>> chessboard_object_points((3, 2), 10.0)[:4].tolist()
    [[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [20.0, 0.0, 0.0], [0.0, 10.0, 0.0]]
    """
    cols, rows = pattern_size
    obj = np.zeros((cols * rows, 3), np.float32)
    obj[:, :2] = np.mgrid[0:cols, 0:rows].T.reshape(-1, 2) * square_size
    return obj


@dataclass(frozen=True)
class ChessboardDetections:
    """Corner detections of :func:`find_chessboard_corners` (only images where the board was found)."""

    object_points: list
    image_points: list
    image_size: tuple[int, int]
    found: list
    missing: list


def _detect_one(item, pattern_size, method):
    img = cv2.imread(str(item), cv2.IMREAD_GRAYSCALE) if isinstance(item, (str, Path)) else np.asarray(item)
    if img is None:
        raise InvalidArgument(f"cannot read image {item}; check the path")
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if method == "sb":
        ok, corners = cv2.findChessboardCornersSB(img, pattern_size, flags=cv2.CALIB_CB_ACCURACY)
    else:
        ok, corners = cv2.findChessboardCorners(img, pattern_size)
        if ok:
            crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 30, 1e-3)
            corners = cv2.cornerSubPix(img, corners, (11, 11), (-1, -1), crit)
    return ok, (None if not ok else corners.reshape(-1, 2).astype(np.float64)), (img.shape[1], img.shape[0])


def find_chessboard_corners(
    images: Iterable[str | Path | NDArray],
    pattern_size: tuple[int, int],
    square_size: float = 1.0,
    method: Literal["classic", "sb"] = "classic",
    workers: int | None = None,
) -> ChessboardDetections:
    """Detect chessboard inner corners in image files or arrays.

    Parameters
    ----------
    images : iterable of path or ndarray
        Image files (read in grayscale) or images.
    pattern_size : (cols, rows)
        Inner corners per row and column, e.g. ``(10, 7)``.
    square_size : float
        Square side (mm) for the object points.
    method : {"classic", "sb"}
        ``cv2.findChessboardCorners`` + ``cv2.cornerSubPix`` (default) or ``cv2.findChessboardCornersSB``.
    workers : int, optional
        Threads (OpenCV releases the GIL); default: number of CPUs.

    Returns
    -------
    ChessboardDetections

    Raises
    ------
    CalibrationError
        The board was found in none of the images (when the classic detector finds none, the
        message says whether the sb detector finds it), or the images differ in size.

    Examples
    --------
    >>> board = np.kron((np.indices((8, 6)).sum(0) % 2), np.ones((40, 40))).astype(np.uint8) * 255
    >>> img = np.pad(board, 40, constant_values=255)
    >>> det = find_chessboard_corners([img], (7, 5))
    >>> len(det.found), det.image_points[0].shape
    (1, (35, 2))
    """
    items = list(images)
    if method not in ("classic", "sb"):
        raise InvalidArgument(f"method must be 'classic' or 'sb', not {method!r}")

    def detect(how: str) -> list[tuple[bool, NDArray | None, tuple[int, int]]]:
        with ThreadPoolExecutor(max_workers=workers or os.cpu_count() or 1) as ex:
            return list(ex.map(lambda it: _detect_one(it, tuple(pattern_size), how), items))

    results = detect(method)
    sizes = {r[2] for r in results}
    if len(sizes) > 1:
        raise CalibrationError(f"images have different sizes {sorted(sizes)}; calibrate each camera/resolution separately")
    found = [i for i, r in enumerate(results) if r[0]]
    if not found:
        hint = "check the pattern size (inner corners COLSxROWS, not squares) and the lighting"
        if method == "classic":  # the sb detector copes with blur and noise that defeat the classic one
            by_sb = sum(r[0] for r in detect("sb"))
            hint = (f"the sb corner detector finds it in {by_sb} of them: rerun with --detector sb (detector = "
                    "\"sb\" in a recipe step, method=\"sb\" in Python)" if by_sb else
                    f"{hint} (the sb corner detector finds none either)")
        raise CalibrationError(f"no {pattern_size[0]}x{pattern_size[1]} chessboard found in {len(items)} "
                               f"image{'s' * (len(items) != 1)}; {hint}")
    obj = chessboard_object_points(pattern_size, square_size)
    label = [str(it) if isinstance(it, (str, Path)) else i for i, it in enumerate(items)]
    return ChessboardDetections(
        object_points=[obj.copy() for _ in found],
        image_points=[results[i][1] for i in found],
        image_size=sizes.pop(),
        found=[label[i] for i in found],
        missing=[label[i] for i in range(len(items)) if i not in set(found)],
    )
