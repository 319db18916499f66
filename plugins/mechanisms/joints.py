"""Joints between rigid marker groups in 3-D (``analysis.md`` §3, issue item 3).

Each body is a ``(T, m, 3)`` array of its markers (mm, NaN where missing, m >= 3 non-collinear).
Poses come from :func:`mirrorlab.plugins.kinematics.rigid.kabsch` against the body's mean shape.

* :func:`spherical_joint` — the point fixed in both bodies (least squares over all frames):
  ``R1 c1 + t1 = R2 c2 + t2``.
* :func:`revolute_joint` — the axis fixed in both bodies: its direction is the null vector of
  ``a1 = R1^T R2 a2`` over all frames, its point the least-squares solution of the spherical
  system closest to the first body's markers.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mirrorlab.plugins.kinematics.rigid import kabsch
from numpy.typing import ArrayLike, NDArray

from .errors import DegenerateGeometry, InvalidPoints
from .grouping import as_tracks

__all__ = ["RevoluteJoint", "SphericalJoint", "body_poses", "revolute_joint", "spherical_joint"]

FloatArray = NDArray[np.float64]


def body_poses(markers: ArrayLike, name: str = "body") -> tuple[FloatArray, FloatArray, FloatArray]:
    """Pose of a rigid marker group per frame against its mean shape (centred at its centroid).

    Parameters
    ----------
    markers : (T, m, 3) positions, mm, NaN where missing.
    name : used in error messages.

    Returns
    -------
    R : (T, 3, 3) body -> world (NaN where fewer than 3 markers are seen).
    t : (T, 3) world position of the shape's centroid, mm.
    shape : (m, 3) body coordinates of the markers, mm.

    Raises
    ------
    InvalidPoints
        Not (T, m, 3), fewer than 3 markers, or no frame with every marker.
    """
    p = as_tracks(markers, name, dims=(3,))
    if p.shape[1] < 3:
        raise InvalidPoints(f"{name}: a 3-D pose needs at least 3 markers, got {p.shape[1]}")
    full = np.flatnonzero(np.isfinite(p).all((1, 2)))
    if full.size == 0:
        raise InvalidPoints(f"{name}: no frame shows all {p.shape[1]} markers; the body shape is undefined")
    shape = p[full[0]] - p[full[0]].mean(0)
    for _ in range(2):                         # the mean shape: align every frame, average, re-centre
        R, t, _, _ = kabsch(shape, p)
        local = np.einsum("tji,tmj->tmi", R, p - t[:, None])
        shape = np.nanmean(local, axis=0)
        shape -= shape.mean(0)
    R, t, _, _ = kabsch(shape, p)
    return R, t, shape


@dataclass(frozen=True)
class SphericalJoint:
    """A ball joint between two bodies.

    Attributes
    ----------
    centre : (T, 3) joint centre in the world per frame (mean of both bodies' predictions, or the
        one available), mm.
    local1, local2 : (3,) the centre in each body's frame (centroid origin), mm.
    residual : (T,) distance between the two bodies' predictions, mm; rms : its RMS.
    condition : ratio of the largest to the smallest singular value of the stacked system; large
        when the relative rotation stays close to one axis (the centre is then poorly determined
        along it, which ``rms`` does not show).
    """

    centre: FloatArray
    local1: FloatArray
    local2: FloatArray
    residual: FloatArray
    rms: float
    condition: float


@dataclass(frozen=True)
class RevoluteJoint:
    """A hinge between two bodies.

    Attributes
    ----------
    point : (T, 3) a point of the axis in the world per frame (the one nearest body 1's centroid), mm.
    direction : (T, 3) unit axis direction in the world.
    local1 : (point (3,), direction (3,)) of the axis in body 1's frame.
    angle : (T,) rotation of body 2 about the axis relative to frame 0 (rad, right-handed about
        ``direction``).
    residual : (T,) distance between the two bodies' axis points, mm; rms : its RMS.
    """

    point: FloatArray
    direction: FloatArray
    local1: tuple[FloatArray, FloatArray]
    angle: FloatArray
    residual: FloatArray
    rms: float


def _common(body1: ArrayLike, body2: ArrayLike) -> tuple[FloatArray, ...]:
    R1, t1, _ = body_poses(body1, "body1")
    R2, t2, _ = body_poses(body2, "body2")
    if len(R1) != len(R2):
        raise InvalidPoints(f"body1 has {len(R1)} frames and body2 {len(R2)}; give both over the same frames")
    ok = np.isfinite(R1).all((1, 2)) & np.isfinite(R2).all((1, 2))
    if ok.sum() < 2:
        raise InvalidPoints(f"the bodies are posed together in {int(ok.sum())} frames; a joint needs at least 2")
    return R1, t1, R2, t2, ok


def _solve_points(R1: FloatArray, t1: FloatArray, R2: FloatArray, t2: FloatArray,
                  ok: NDArray[np.bool_]) -> tuple[FloatArray, NDArray[np.float64], FloatArray]:
    A = np.concatenate([R1[ok], -R2[ok]], axis=2).reshape(-1, 6)
    b = (t2[ok] - t1[ok]).reshape(-1)
    sol, _, _, sv = np.linalg.lstsq(A, b, rcond=None)
    return sol, sv, A


def spherical_joint(body1: ArrayLike, body2: ArrayLike) -> SphericalJoint:
    """Least-squares centre of rotation between two rigid marker groups (a ball joint).

    Parameters
    ----------
    body1, body2 : (T, m1, 3), (T, m2, 3) markers of each body, mm, NaN where missing.

    Returns
    -------
    SphericalJoint

    Raises
    ------
    InvalidPoints
        Bad shapes or too few posed frames.
    DegenerateGeometry
        The relative rotation keeps one axis (a hinge: use :func:`revolute_joint`) or is too small.

    Examples
    --------
    >>> from scipy.spatial.transform import Rotation
    >>> rng = np.random.default_rng(0)
    >>> q1, q2, c = rng.normal(size=(4, 3)) * 50, rng.normal(size=(4, 3)) * 50, np.array([10.0, 20, 30])
    >>> R1, R2 = Rotation.random(20, random_state=1).as_matrix(), Rotation.random(20, random_state=2).as_matrix()
    >>> t1 = rng.normal(size=(20, 3)) * 100
    >>> t2 = t1 + np.einsum("tij,j->ti", R1, c) - np.einsum("tij,j->ti", R2, c)   # c is shared
    >>> j = spherical_joint(np.einsum("tij,mj->tmi", R1, q1) + t1[:, None], np.einsum("tij,mj->tmi", R2, q2) + t2[:, None])
    >>> bool(np.allclose(j.centre, np.einsum("tij,j->ti", R1, c) + t1)), j.rms < 1e-9
    (True, True)
    """
    R1, t1, R2, t2, ok = _common(body1, body2)
    sol, sv, _ = _solve_points(R1, t1, R2, t2, ok)
    if sv[-1] < 1e-6 * sv[0]:
        raise DegenerateGeometry(f"the relative rotation of the bodies keeps one axis (singular values "
                                 f"{sv[0]:.3g} ... {sv[-1]:.3g}): the joint centre is not unique; a hinge? use "
                                 "revolute_joint, or give frames with rotation about more than one axis")
    c1, c2 = sol[:3], sol[3:]
    p1 = np.einsum("tij,j->ti", R1, c1) + t1
    p2 = np.einsum("tij,j->ti", R2, c2) + t2
    res = np.linalg.norm(p1 - p2, axis=1)
    with np.errstate(invalid="ignore"):
        centre = np.nanmean(np.stack([p1, p2]), axis=0)          # one body's prediction where the other is unposed
    return SphericalJoint(centre, c1, c2, res, float(np.sqrt(np.nanmean(res**2))), float(sv[0] / sv[-1]))


def revolute_joint(body1: ArrayLike, body2: ArrayLike) -> RevoluteJoint:
    """Least-squares hinge axis between two rigid marker groups.

    Parameters
    ----------
    body1, body2 : (T, m1, 3), (T, m2, 3) markers of each body, mm, NaN where missing.

    Returns
    -------
    RevoluteJoint

    Raises
    ------
    InvalidPoints
        Bad shapes or too few posed frames.
    DegenerateGeometry
        The bodies do not rotate relative to each other (no axis).
    """
    R1, t1, R2, t2, ok = _common(body1, body2)
    Q = np.einsum("tji,tjk->tik", R1[ok], R2[ok])                                # body 2 -> body 1
    M = np.concatenate([np.broadcast_to(np.eye(3), Q.shape), -Q], axis=2).reshape(-1, 6)
    _, sv, vt = np.linalg.svd(M)
    if sv[-2] < 1e-6 * sv[0]:
        raise DegenerateGeometry("the bodies barely rotate relative to each other: no hinge axis; give frames "
                                 "with a larger relative rotation")
    n = vt[-1]
    a1 = n[:3] / np.linalg.norm(n[:3])
    sol, _, _ = _solve_points(R1, t1, R2, t2, ok)
    c1 = sol[:3] - (sol[:3] @ a1) * a1                           # the axis point nearest body 1's centroid
    p1 = np.einsum("tij,j->ti", R1, c1) + t1
    # the same point in body 2: least squares of R2 c2 + t2 = p1 over the posed frames
    c2 = np.linalg.lstsq(R2[ok].reshape(-1, 3), (p1[ok] - t2[ok]).reshape(-1), rcond=None)[0]
    p2 = np.einsum("tij,j->ti", R2, c2) + t2
    res = np.linalg.norm(np.cross(p2 - p1, np.einsum("tij,j->ti", R1, a1)), axis=1)     # off-axis distance
    direction = np.einsum("tij,j->ti", R1, a1)
    Qall = np.einsum("tji,tjk->tik", R1, R2)
    rel = np.einsum("tij,jk->tik", Qall, np.swapaxes(Qall[np.flatnonzero(ok)[0]], 0, 1))  # relative to frame 0
    cosang = (np.einsum("tii->t", rel) - 1) / 2
    sinang = 0.5 * np.einsum("ti,i->t", np.stack([rel[:, 2, 1] - rel[:, 1, 2], rel[:, 0, 2] - rel[:, 2, 0],
                                                  rel[:, 1, 0] - rel[:, 0, 1]], -1), a1)
    angle = np.arctan2(sinang, cosang)
    return RevoluteJoint(p1, direction, (c1, a1), angle, res, float(np.sqrt(np.nanmean(res**2))))
