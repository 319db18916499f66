"""Rounding bounds of the photogrammetry computations, derived from their conditioning (issue 19).

Shared by tests/plugins/photogrammetry and tests/plugins/photogrammetry; each bound is
``tests.tolerances.roundoff`` with the condition number of the problem at hand.
"""

from __future__ import annotations

import numpy as np
from mirrorlab.plugins.photogrammetry.cameras import PlaneCalibration
from mirrorlab.plugins.photogrammetry.central import CentralCamera, reconstruct_chain_central
from numpy.typing import ArrayLike

from tests.tolerances import roundoff


def map_roundoff(cal: PlaneCalibration, image_xy: ArrayLike, plane_scale: float) -> float:
    """Rounding bound (mm) of ``cal.map_to_plane`` at ``image_xy``.

    A zero-residual fit leaves the parameters a relative forward error <= kappa eps (kappa =
    ``cal.condition``: the normalised design matrix's, or the LM Jacobian's); the map at normalised
    image radius |u| multiplies it by at most (1 + |u|)^2 (quadratic terms, projective denominator),
    applied to plane coordinates of magnitude ``plane_scale``. ops = 6 terms of a design row.
    """
    u = (np.asarray(image_xy, float) - cal.center) / cal.scale
    reach = (1.0 + np.nanmax(np.linalg.norm(u, axis=-1))) ** 2  # NaN: a point not seen
    return roundoff(cond=cal.condition, scale=plane_scale * reach, ops=6)


def chain_condition(xy: ArrayLike, lengths: ArrayLike, cam: CentralCamera, h: float = 1e-9, **choice: ArrayLike) -> float:
    """Relative condition number of the chain reconstruction: |dP/d input| |input| / |P| (central differences).

    Inputs are the film coordinates and the link lengths. The rounding inside a link, ~eps (b^2 + |a c|)
    in the discriminant (cancelling near a tangent ray), equals a relative change of that link's length
    D by eps (2 |Q|^2 + D^2) / (2 D^2) (Q = previous marker - S, c = |Q|^2 - D^2): the length
    derivatives are weighted by that factor, so the condition covers the cancellation and its
    propagation along the chain. ``choice``: the ``signs`` / ``reference`` that fix every root.
    """
    xy = np.asarray(xy, float)
    lengths = np.broadcast_to(np.asarray(lengths, float), xy.shape[:-1]).copy()

    def rec(z: np.ndarray, d: np.ndarray) -> np.ndarray:
        return reconstruct_chain_central(z, d, cam, **choice).points

    P = rec(xy, lengths)
    Q = np.concatenate([np.broadcast_to(cam.K, P[..., :1, :].shape), P[..., :-1, :]], axis=-2) - cam.camera_center
    weight = (2 * np.sum(Q * Q, axis=-1) + lengths**2) / (2 * lengths**2)
    gain = np.zeros(xy.shape[:-2])
    step = h * np.abs(xy).max()
    for idx in np.ndindex(xy.shape[-2:]):
        d = np.zeros_like(xy)
        d[(...,) + idx] = step
        gain += np.abs((rec(xy + d, lengths) - rec(xy - d, lengths)) / (2 * step)).max(axis=(-2, -1)) * np.abs(xy).max()
    for i in range(xy.shape[-2]):
        d = np.zeros_like(lengths)
        d[..., i] = h * lengths[..., i]
        dP = np.abs(rec(xy, lengths + d) - rec(xy, lengths - d)).max(axis=(-2, -1)) / (2 * h)
        gain += dP * weight[..., i]
    return float(gain.max() / np.abs(P).max())


def chain_roundoff(xy: ArrayLike, lengths: ArrayLike, cam: CentralCamera, **choice: ArrayLike) -> float:
    """Rounding bound (mm) of a reconstructed chain: ~10 roundings per link (w, b, c, the discriminant,
    its root), each an eps-sized input perturbation; the condition sums them over the links."""
    P = reconstruct_chain_central(xy, lengths, cam, **choice).points
    return roundoff(cond=chain_condition(xy, lengths, cam, **choice), scale=np.abs(P).max(), ops=10)


def pair_planes(P: np.ndarray, Pv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """|A_k| of the pair-plane normals A_k = P^ x P'^ (3.8) and the singular values of the stacked unit A_k."""
    A = np.cross(P / np.linalg.norm(P, axis=1, keepdims=True), Pv / np.linalg.norm(Pv, axis=1, keepdims=True))
    a = np.linalg.norm(A, axis=1)
    return a, np.linalg.svd(A / a[:, None], compute_uv=False)


def normal_condition(P: np.ndarray, Pv: np.ndarray) -> float:
    """Condition of the mirror normal from ray pairs: a unit A_k has a rounding error eps / |A_k|
    (nearly parallel rays), and the null vector of the stacked unit A_k moves by that over sigma_2 /
    sigma_1 (the gap to the next singular value)."""
    a, s = pair_planes(P, Pv)
    return float(s[0] / s[1] / a.min())


def normal_roundoff(P: np.ndarray, Pv: np.ndarray, ray_error: float = 0.0) -> float:
    """Bound of a unit normal estimated from the pairs: ~10 roundings per ray and cross product, plus
    rays that carry an angular error ``ray_error`` (rad) from a camera model, amplified alike."""
    return roundoff(cond=normal_condition(P, Pv), ops=10) + normal_condition(P, Pv) * ray_error


def triangulation_condition(cos_angle: ArrayLike, views: ArrayLike = 2) -> float:
    """Condition of a ray intersection with rays at |cos| = c.

    The closest point's normal matrix sum(I - d d^T) over V views has eigenvalues in [1 - c, V], so
    condition V / (1 - c); the two-ray closed form (3.5)-(3.6) cancels in |u1|^2 |u2|^2 (1 - k^2),
    2 / (1 - k^2) ~ 1 / (1 - c) as well.
    """
    return float(np.nanmax(np.asarray(views) / (1 - np.asarray(cos_angle))))


def triangulation_roundoff(cos_angle: ArrayLike, scale: float, views: ArrayLike = 2, ray_error: float = 0.0) -> float:
    """Bound (mm) of a ray intersection: ~10 roundings of ``scale`` (the largest coordinate or depth
    involved, mm), plus rays with an angular error ``ray_error`` (rad) moving the point by up to
    ``scale * ray_error``, both amplified by :func:`triangulation_condition`."""
    kappa = triangulation_condition(cos_angle, views)
    return roundoff(cond=kappa, scale=scale, ops=10) + kappa * scale * ray_error


def plane_ray_error(cal: PlaneCalibration, image_xy: ArrayLike, plane_scale: float) -> float:
    """Angular error (rad) of ``cal.rays`` at ``image_xy``: the map's bound over the distance from the
    camera centre to the calibration plane (the shortest |C - F1|)."""
    return map_roundoff(cal, image_xy, plane_scale) / abs(cal.camera_center[2] - cal.plane_z)


#: Angular error (rad) of PinholeCamera.rays: cv2.undistortPoints iterates until its step is 1e-14
#: (normalised image units, i.e. radians near the axis; cameras.PinholeCamera.normalized).
UNDISTORT_TOL = 1e-14


def parallel_roundoff(P: np.ndarray, lengths: ArrayLike, reach: float | None = None) -> float:
    """Rounding bound (mm) of a chain from a parallel projection, true points P (..., N, 3) (NaN: not seen).

    A link's depth step dZ = sqrt(D^2 - r^2) cancels when the link lies nearly in the image plane:
    the radicand's rounding, eps D (D + reach) (r from differences of image coordinates of magnitude
    ``reach``, default |P|), moves dZ by that over |dZ|. Links add up (no amplification along the
    chain), plus the summation's rounding of ``reach``.
    """
    lengths = np.asarray(lengths, float)
    prev = np.concatenate([np.zeros_like(P[..., :1, :]), P[..., :-1, :]], axis=-2)
    dz = np.abs(P[..., 2] - prev[..., 2])
    reach = float(np.nanmax(np.abs(P))) if reach is None else reach
    with np.errstate(divide="ignore"):
        per_frame = np.nansum(lengths * (lengths + reach) / dz, axis=-1) + P.shape[-2] * reach
    return roundoff(scale=float(per_frame.max()), ops=6)
