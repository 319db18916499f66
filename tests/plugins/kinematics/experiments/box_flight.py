"""The thrown box filmed in the virtual lab, measured end to end (``kinematics.md`` §5, Fig. 3.30).

The thesis's measurement chain with a modern rigid fit, on the lab of
:func:`~mirrorlab.instruments.virtual_lab.box_flight.thesis_box_lab`:

1. exact image positions of each vertex directly and in the mirror (the lab's truth: a vertex is
   hidden by the box itself, or lost when its reflected ray misses the finite mirror);
2. Gaussian digitising noise on the film coordinates (``noise_px``);
3. mirror triangulation (:func:`~mirrorlab.plugins.photogrammetry.triangulate_mirror`, eqs
   3.1-3.7) of every vertex seen in **both** views;
4. least-squares fit of the known box to the reconstructed vertices per frame
   (:func:`~mirrorlab.plugins.kinematics.kabsch`), angular velocity from a spline of the fitted
   rotations (:func:`~mirrorlab.plugins.kinematics.omega_from_rotations`), and the angular momentum
   about the centre of mass (3.48) with the uniform-box inertia.

Torque-free flight keeps ``H_G`` constant, so the spread of ``|H_G|`` measures the chain. The
per-frame visibility measures are the number of vertices seen in both views and the
conditioning of the rigid fit (:func:`rotation_sensitivity`). It joins the virtual lab (an
instrument package) and the plugins it validates, which import nothing of each other, so it lives
here, with the tests and ``docs/validation/box_flight.py`` that use it. Units: mm, s, rad, px;
``H`` in kg·m²/s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mirrorlab.instruments.virtual_lab import VirtualLab
from mirrorlab.instruments.virtual_lab.box_flight import THESIS_BOX_RATE, thesis_box_lab
from mirrorlab.instruments.virtual_lab.optics import Mirror
from mirrorlab.instruments.virtual_lab.scenes import BoxScene
from mirrorlab.instruments.virtual_lab.truth import LabTruth
from mirrorlab.plugins.kinematics import angular_momentum, kabsch, omega_from_rotations
from mirrorlab.plugins.kinematics.synthetic import box_inertia
from mirrorlab.plugins.photogrammetry import PinholeCamera, triangulate_mirror
from numpy.typing import ArrayLike, NDArray

__all__ = ["BoxFlight", "rotation_sensitivity", "simulate_box_flight"]

FloatArray = NDArray[np.float64]


def rotation_sensitivity(reference: ArrayLike, used: ArrayLike) -> FloatArray:
    """Conditioning of the rigid fit: RMS rotation error (rad) per mm of point noise.

    For isotropic point noise ``sigma`` (mm) the rotation error of a least-squares rigid fit to
    the points ``q_i`` has covariance ``sigma² J⁻¹`` with ``J = sum(|d_i|² I - d_i d_iᵀ)``,
    ``d_i = q_i - mean(q)`` over the points used (the second moment of the visible point set).
    The figure returned is ``sqrt(trace(J⁻¹))``; ``inf`` when fewer than 3 points (or collinear).

    Parameters
    ----------
    reference : (M, 3) array_like, mm
        Body-frame marker coordinates.
    used : (T, M) array_like of bool
        Markers entering each frame's fit.

    Returns
    -------
    ndarray, shape (T,), rad/mm

    Examples
    --------
    >>> from mirrorlab.plugins.kinematics.synthetic import box_vertices
    >>> q = box_vertices([200.0, 200.0, 300.0])
    >>> s = rotation_sensitivity(q, [[True] * 8, [True] * 4 + [False] * 4, [True, True] + [False] * 6])
    >>> bool(s[0] < s[1]), bool(np.isinf(s[2]))
    (True, True)
    """
    q = np.asarray(reference, dtype=float)
    w = np.asarray(used, dtype=bool).astype(float)
    n = w.sum(1)
    with np.errstate(invalid="ignore", divide="ignore"):
        c = (w @ q) / n[:, None]
    d = (q[None] - c[:, None]) * w[..., None]
    S = np.einsum("tmi,tmj->tij", d, d)
    J = np.trace(S, axis1=1, axis2=2)[:, None, None] * np.eye(3) - S
    out = np.full(n.size, np.inf)
    ok = n >= 3
    if ok.any():
        ev = np.linalg.eigvalsh(J[ok])
        good = ev[:, 0] > 1e-9 * ev[:, -1]
        val = np.full(ev.shape[0], np.inf)
        val[good] = np.sqrt(np.sum(1.0 / ev[good], axis=1))
        out[ok] = val
    return out


@dataclass(frozen=True)
class BoxFlight:
    """One simulated and measured flight of the box.

    Attributes
    ----------
    t : (T,) s.
    truth : LabTruth, exact positions and images.
    markers : (T, 8, 3) mm, triangulated vertices, NaN unless seen in both views.
    n_both : (T,) vertices seen directly and in the mirror.
    sensitivity : (T,) rad/mm, :func:`rotation_sensitivity` of the vertices used.
    height : (T,) mm, true height of the box centre.
    R : (T, 3, 3) fitted body -> world rotation (NaN with < 3 vertices).
    omega : (T, 3) rad/s, world frame.
    H : (T, 3) kg·m²/s, measured angular momentum about G.
    H_true : (3,) kg·m²/s, the constant true value.
    rotation_error : (T,) rad, angle of ``R_fit R_trueᵀ``.
    noise_px : float, digitising noise (px, 1 sigma per coordinate).
    noise_object_mm : float, the same noise in object space at the mean camera distance, mm.
    """

    t: FloatArray
    truth: LabTruth
    markers: FloatArray
    n_both: NDArray[np.int_]
    sensitivity: FloatArray
    height: FloatArray
    R: FloatArray
    omega: FloatArray
    H: FloatArray
    H_true: FloatArray
    rotation_error: FloatArray
    noise_px: float
    noise_object_mm: float

    @property
    def H_error(self) -> FloatArray:
        """(T,) per-frame error ``|H - H_true| / |H_true|``."""
        return np.linalg.norm(self.H - self.H_true, axis=1) / np.linalg.norm(self.H_true)

    @property
    def H_norm(self) -> FloatArray:
        """(T,) ``|H_G|`` in kg·m²/s."""
        return np.linalg.norm(self.H, axis=1)

    def variation(self, trim: int = 0) -> float:
        """``(max - min) / mean`` of ``|H_G|`` over the finite frames, ``trim`` frames cut at each end."""
        h = self.H_norm[trim:self.t.size - trim]
        h = h[np.isfinite(h)]
        return float(np.ptp(h) / h.mean()) if h.size else float("nan")


def simulate_box_flight(lab: VirtualLab | None = None, rate: float = THESIS_BOX_RATE, noise_px: float = 0.0,
                        seed: int = 0, method: str = "smoothing_spline", **params: object) -> BoxFlight:
    """Film, digitise, triangulate and fit the thrown box; angular momentum per frame.

    Parameters
    ----------
    lab : VirtualLab, optional
        A lab whose scene is a :class:`BoxScene` and which has one mirror (default
        :func:`thesis_box_lab`). The camera, ``G`` and the mirror normal are taken as known
        (perfect calibration).
    rate : float, frames/s
        Sampling over ``[0, scene.duration]``.
    noise_px : float, px
        Gaussian digitising noise added to every image coordinate (1 sigma).
    seed : int
        Seed of the noise.
    method, **params
        Differentiation of the fitted rotations (:func:`~mirrorlab.plugins.kinematics.derivatives`),
        e.g. ``method="smoothing_spline", lam=0.0`` for exact data, GCV by default.

    Returns
    -------
    BoxFlight

    Raises
    ------
    ValueError
        The lab's scene is not a BoxScene, it has no mirror, or ``rate`` / ``noise_px`` are invalid.

    Examples
    --------
    >>> f = simulate_box_flight(rate=42.0, method="smoothing_spline", lam=0.0)
    >>> f.t.size, int(f.n_both.max()), bool(f.variation(trim=3) < 1e-2)
    (43, 6, True)
    """
    lab = thesis_box_lab() if lab is None else lab
    scene = lab.scene
    if not isinstance(scene, BoxScene):
        raise ValueError(f"simulate_box_flight needs a BoxScene, got {type(scene).__name__}; use thesis_box_lab()")
    if len(lab.mirrors) != 1:
        raise ValueError(f"simulate_box_flight needs exactly one mirror, the lab has {len(lab.mirrors)}")
    if rate <= 0 or noise_px < 0:
        raise ValueError(f"rate must be > 0 frames/s and noise_px >= 0 px (got {rate}, {noise_px})")
    duration = float(scene.duration or 1.0)
    t = np.arange(int(np.floor(duration * rate + 1e-9)) + 1) / rate
    truth = lab.truth(t)
    mirror: Mirror = lab.mirrors[0]
    c = lab.camera
    camera = PinholeCamera(c.K, c.dist, c.R, c.t, c.image_size)     # the plugin's model of the lab's camera
    rng = np.random.default_rng(seed)
    xy_real = truth.real_xy + rng.normal(0.0, noise_px, truth.real_xy.shape)
    xy_virt = truth.virtual_xy[:, 0] + rng.normal(0.0, noise_px, truth.real_xy.shape)
    both = np.isfinite(xy_real).all(-1) & np.isfinite(xy_virt).all(-1)
    markers = np.full(truth.positions.shape, np.nan)
    if both.any():
        tri = triangulate_mirror(camera.camera_center, mirror.centre, mirror.normal,
                                 camera.rays(xy_real[both]), camera.rays(xy_virt[both]), on_degenerate="flag")
        markers[both] = np.where(tri.degenerate[:, None], np.nan, tri.points)
    used = np.isfinite(markers).all(-1)
    ref = scene.vertices
    R, _, _, n = kabsch(ref, markers)
    omega = omega_from_rotations(t, R, method=method, **params)
    inertia = box_inertia(scene.mass, np.asarray(scene.size) / 1000.0)
    H = angular_momentum(np.swapaxes(R, -1, -2), inertia, omega)
    R_true = truth.analytic["R"]
    cos = (np.einsum("tij,tij->t", R, R_true) - 1.0) / 2.0
    rot_err = np.arccos(np.clip(cos, -1.0, 1.0))
    dist = np.linalg.norm(truth.analytic["centre"] - camera.camera_center, axis=1).mean()
    fx = float(camera.K[0, 0])
    return BoxFlight(t, truth, markers, n.astype(int), rotation_sensitivity(ref, used),
                     truth.analytic["centre"][:, 1].copy(), R, omega, H, truth.analytic["H_world"][0].copy(),
                     rot_err, float(noise_px), float(noise_px * dist / fx))
