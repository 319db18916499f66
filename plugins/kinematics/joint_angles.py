"""Upper-limb joint angles: thesis eqs (6.4)-(6.10) (analysis.md §8) and ISB joint coordinate systems.

Thesis markers: P0 manubrium (trunk reference), P1 acromion, P2 elbow, P3 wrist, P4/P5 the ends of
the gripped bar (P5 = thumb-side end), P6 = (P4 + P5)/2. :func:`upper_limb_angles` returns both the
literal (unsigned) angles as printed and mirrorlab's signed variants (§8.3).

ISB (Wu et al. 2005, J Biomech 38:981): :func:`isb_thorax_frame`, :func:`isb_humerus_frame`,
:func:`isb_forearm_frame` build segment frames from bony landmarks; :func:`isb_shoulder_angles`
(thoraco-humeral Y-X-Y, or X-Z-Y near gimbal lock) and :func:`isb_elbow_angles` (Z-X-Y) decompose
relative rotations with ``scipy.spatial.transform.Rotation.as_euler`` (intrinsic sequences).

Units: positions in mm, angles in rad; right-handed world frame with ``vertical`` up.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial.transform import Rotation

from .errors import DegenerateJointGeometry, first_index

__all__ = [
    "UpperLimbAngles",
    "upper_limb_angles",
    "elbow_flexion",
    "isb_thorax_frame",
    "isb_humerus_frame",
    "isb_forearm_frame",
    "isb_shoulder_angles",
    "isb_elbow_angles",
]

FloatArray = NDArray[np.float64]
_TOL = 1e-9


def _dot(x: FloatArray, y: FloatArray) -> FloatArray:
    return np.einsum("...i,...i", x, y)


def _norm(x: FloatArray) -> FloatArray:
    return np.linalg.norm(x, axis=-1)


def _unit(v: FloatArray, what: str, ref: FloatArray | None, on_degenerate: str) -> FloatArray:
    """Normalise; a vector shorter than _TOL * ref (or exactly zero) is degenerate."""
    n = _norm(v)
    scale = n if ref is None else ref
    bad = n <= _TOL * scale
    if ref is None:
        bad = n == 0
    if np.any(bad):
        if on_degenerate == "raise":
            k = first_index(bad)
            raise DegenerateJointGeometry(
                f"{what} at frame {k}; the angle is undefined in this posture - drop the frame or "
                "pass on_degenerate='nan'"
            )
        v = np.where(bad[..., None], np.nan, v)
    with np.errstate(invalid="ignore", divide="ignore"):
        return v / n[..., None]


@dataclass(frozen=True)
class UpperLimbAngles:
    """Upper-limb angles (rad), arrays over frames.

    Literal forms of analysis.md §8.2: ``theta0``..``theta6`` (unsigned, as printed).
    Signed forms of §8.3: ``theta0s`` (flexion +), ``theta1s`` (abduction), ``theta2``
    (humeral rotation, = arcsin(t1.t2), also the literal value), ``phi12`` (signed twist of plane
    P1P2P3 from plane P0P1P2 about P12), ``theta3`` (elbow flexion, 0 = straight), ``theta4s``
    (forearm twist, minus ``pronation_offset``), ``theta5s`` (palmar/dorsal), ``theta6s``
    (ulnar/radial deviation). Hand angles are NaN when the bar markers are not given.
    """

    theta0: FloatArray
    theta1: FloatArray
    theta2: FloatArray
    theta3: FloatArray
    theta4: FloatArray
    theta5: FloatArray
    theta6: FloatArray
    theta0s: FloatArray
    theta1s: FloatArray
    phi12: FloatArray
    theta4s: FloatArray
    theta5s: FloatArray
    theta6s: FloatArray


def upper_limb_angles(
    P0: ArrayLike,
    P1: ArrayLike,
    P2: ArrayLike,
    P3: ArrayLike,
    P4: ArrayLike | None = None,
    P5: ArrayLike | None = None,
    side: str = "right",
    vertical: ArrayLike = (0.0, 1.0, 0.0),
    pronation_offset: float = 0.0,
    on_degenerate: str = "raise",
) -> UpperLimbAngles:
    """Thesis upper-limb angles θ0-θ6 (eqs 6.4-6.10 with errata) and their signed variants.

    Parameters
    ----------
    P0, P1, P2, P3 : array_like, shape (..., 3)
        Manubrium, acromion, elbow and wrist positions (mm).
    P4, P5 : array_like, shape (..., 3), optional
        Ends of the gripped bar (P5 thumb-side). Without them θ4-θ6 are NaN.
    side : {"right", "left"}
        Arm side; sets σ = -1 (right) / +1 (left) so that flexion θ0s is positive on both sides.
    vertical : array_like, shape (3,)
        Laboratory up direction Y (thesis: Y vertical).
    pronation_offset : float
        Subtracted from θ4s (wrapped to (-π, π]); ±π/2 makes the mid (thumb-up) grip read 0, the
        thesis's ±1.57 rad convention. Default 0: zero when the bar plane is perpendicular to
        the arm plane.
    on_degenerate : {"raise", "nan"}
        Raise :class:`DegenerateJointGeometry` (naming angle and frame) or return NaN.

    Returns
    -------
    UpperLimbAngles

    Examples
    --------
    >>> P0 = np.zeros(3); P1 = np.array([0.0, 0, 200])           # X forward, Y up, Z right
    >>> a = 0.5                                                    # forward flexion (rad)
    >>> P2 = P1 + 300 * np.array([np.sin(a), -np.cos(a), 0.0])
    >>> P3 = P2 + 250 * np.array([1.0, 0, 0])
    >>> ang = upper_limb_angles(P0, P1, P2, P3)
    >>> round(float(ang.theta0s), 12), round(float(ang.theta0), 6) == round(np.pi - a, 6)
    (0.5, True)
    """
    p0, p1, p2, p3 = (np.asarray(p, dtype=float) for p in (P0, P1, P2, P3))
    sigma = {"right": -1.0, "left": 1.0}.get(side)
    if sigma is None:
        raise DegenerateJointGeometry(f"side must be 'right' or 'left', got {side!r}")
    Y = np.asarray(vertical, dtype=float)
    Y = Y / np.linalg.norm(Y)
    P01, P12, P23 = p1 - p0, p2 - p1, p3 - p2
    i = _unit(P01, "P0 and P1 coincide (shoulder frame i)", None, on_degenerate)
    j = _unit(Y - _dot(np.broadcast_to(Y, i.shape), i)[..., None] * i,
              "P01 is vertical (shoulder frame j)", np.ones(i.shape[:-1]), on_degenerate)
    k = np.cross(i, j)
    ui, uj, uk = _dot(P12, i), _dot(P12, j), _dot(P12, k)
    n12 = _norm(P12)
    jk = np.hypot(uj, uk)
    ij = np.hypot(ui, uj)
    for val, msg in ((jk, "P12 parallel to i: θ0 projection is empty"),
                     (ij, "P12 parallel to k: θ1 projection is empty")):
        _unit(np.stack([val, np.zeros_like(val), np.zeros_like(val)], -1), msg, n12, on_degenerate)
    with np.errstate(invalid="ignore", divide="ignore"):
        theta0 = np.arccos(np.clip(uj / jk, -1, 1))  # (6.4)
        theta1 = np.arccos(np.clip(uj / ij, -1, 1))  # (6.5)
    theta0s = np.arctan2(sigma * uk, -uj)
    theta1s = np.arctan2(ui, -uj)
    n01 = _norm(P01)
    n23 = _norm(P23)
    e12 = _unit(P12, "P1 and P2 coincide", None, on_degenerate)
    e23 = _unit(P23, "P2 and P3 coincide", None, on_degenerate)
    t1 = _unit(np.cross(P01, P12), "P12 parallel to P01: plane P0P1P2 (t1, θ2) undefined", n01 * n12, on_degenerate)
    t2 = _unit(np.cross(P12, P23), "elbow fully extended: plane P1P2P3 (t2, θ2/θ4) undefined",
               n12 * n23, on_degenerate)
    c12 = np.clip(_dot(t1, t2), -1, 1)
    theta2 = np.arcsin(c12)  # (6.6): cos(pi/2 - θ2) = t1.t2
    phi12 = np.arctan2(_dot(np.cross(t1, t2), e12), c12)
    with np.errstate(invalid="ignore", divide="ignore"):
        theta3 = np.arccos(np.clip(_dot(P12, P23) / (n12 * n23), -1, 1))  # (6.7)
    nan = np.full(theta3.shape, np.nan)
    theta4 = theta5 = theta6 = theta4s = theta5s = theta6s = nan
    if P4 is not None and P5 is not None:
        p4, p5 = np.asarray(P4, dtype=float), np.asarray(P5, dtype=float)
        p6 = 0.5 * (p4 + p5)
        P34, P35, P36, P45 = p4 - p3, p5 - p3, p6 - p3, p5 - p4
        n = np.cross(P34, P35)
        _unit(n, "P3, P4, P5 collinear: hand plane undefined (θ4-θ6)", _norm(P34) * _norm(P35), on_degenerate)
        t3 = _unit(np.cross(n, e23), "hand-plane normal parallel to P23: t3 undefined (θ4-θ6)",
                   _norm(n), on_degenerate)
        t3 = np.where((_dot(t3, P45) < 0)[..., None], -t3, t3)
        c23 = np.clip(_dot(t2, t3), -1, 1)
        theta4 = np.arccos(c23)  # (6.8)
        theta4s = np.arctan2(_dot(np.cross(t2, t3), e23), c23)
        theta4s = np.angle(np.exp(1j * (theta4s - pronation_offset)))
        iw, jw = t3, e23
        kw = np.cross(iw, jw)
        n36 = _norm(P36)
        with np.errstate(invalid="ignore", divide="ignore"):
            theta5 = np.arccos(np.clip(_dot(P36, jw) / n36, -1, 1))  # (6.9)
            theta6 = np.arccos(np.clip(_dot(P36, kw) / n36, -1, 1))  # (6.10) as printed
        theta5s = np.arctan2(_dot(P36, kw), _dot(P36, jw))
        theta6s = np.arctan2(_dot(P36, iw), _dot(P36, jw))
    return UpperLimbAngles(theta0, theta1, theta2, theta3, theta4, theta5, theta6,
                           theta0s, theta1s, phi12, theta4s, theta5s, theta6s)


def elbow_flexion(shoulder: ArrayLike, elbow: ArrayLike, wrist: ArrayLike) -> FloatArray:
    """Three-point elbow flexion θ3 (6.7): angle between upper arm and forearm, 0 = straight (rad).

    Examples
    --------
    >>> round(float(np.degrees(elbow_flexion([0, 300.0, 0], [0.0, 0, 0], [250.0, 0, 0]))), 9)
    90.0
    """
    s, e, w = (np.asarray(x, dtype=float) for x in (shoulder, elbow, wrist))
    u, v = e - s, w - e
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.arccos(np.clip(_dot(u, v) / (_norm(u) * _norm(v)), -1, 1))


def _frame(x: FloatArray, y: FloatArray, z: FloatArray) -> FloatArray:
    """Stack unit axes as columns: R maps segment to world coordinates."""
    return np.stack([x, y, z], -1)


def isb_thorax_frame(IJ: ArrayLike, PX: ArrayLike, C7: ArrayLike, T8: ArrayLike) -> FloatArray:
    """ISB thorax frame (Wu 2005 §2.3.1): Y up along mid(PX,T8)->mid(IJ,C7), Z right, X forward.

    Returns
    -------
    ndarray, shape (..., 3, 3)
        Columns = X, Y, Z axes in world coordinates (segment -> world rotation).
    """
    ij, px, c7, t8 = (np.asarray(v, dtype=float) for v in (IJ, PX, C7, T8))
    low, up = 0.5 * (px + t8), 0.5 * (ij + c7)
    y = _unit(up - low, "thorax: IJ/C7 and PX/T8 midpoints coincide", None, "raise")
    z = _unit(np.cross(c7 - ij, low - ij), "thorax: IJ, C7, PX/T8 collinear", None, "raise")
    return _frame(np.cross(y, z), y, z)


def isb_humerus_frame(GH: ArrayLike, EL: ArrayLike, EM: ArrayLike, side: str = "right") -> FloatArray:
    """ISB humerus frame, option 1 (Wu 2005 §3.3.4): Y = mid(EL,EM)->GH, X ⊥ plane GH-EL-EM forward.

    ``side="left"`` uses EM->EL reversed so the frame stays right-handed with Z to the right.
    """
    gh, el, em = (np.asarray(v, dtype=float) for v in (GH, EL, EM))
    y = _unit(gh - 0.5 * (el + em), "humerus: GH coincides with the epicondyle midpoint", None, "raise")
    lat = el - em if side == "right" else em - el
    x = _unit(np.cross(y, lat), "humerus: GH, EL, EM collinear", None, "raise")
    return _frame(x, y, np.cross(x, y))


def isb_forearm_frame(US: ArrayLike, RS: ArrayLike, EL: ArrayLike, EM: ArrayLike, side: str = "right") -> FloatArray:
    """ISB forearm frame (Wu 2005 §3.3.5): Y = US->mid(EL,EM), X ⊥ plane US-RS-mid forward, Z right."""
    us, rs, el, em = (np.asarray(v, dtype=float) for v in (US, RS, EL, EM))
    y = _unit(0.5 * (el + em) - us, "forearm: US coincides with the epicondyle midpoint", None, "raise")
    lat = rs - us if side == "right" else us - rs
    x = _unit(np.cross(y, lat), "forearm: US, RS and the elbow midpoint collinear", None, "raise")
    return _frame(x, y, np.cross(x, y))


def _relative_euler(R_prox: ArrayLike, R_dist: ArrayLike, seq: str) -> FloatArray:
    Rp, Rd = np.asarray(R_prox, dtype=float), np.asarray(R_dist, dtype=float)
    rel = np.swapaxes(Rp, -1, -2) @ Rd
    shape = rel.shape[:-2]
    flat = rel.reshape(-1, 3, 3)
    out = np.full((flat.shape[0], 3), np.nan)
    ok = np.all(np.isfinite(flat), axis=(1, 2))
    if np.any(ok):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # gimbal lock: reported via the flag
            out[ok] = Rotation.from_matrix(flat[ok]).as_euler(seq)
    return out.reshape(shape + (3,))


def isb_shoulder_angles(
    R_thorax: ArrayLike, R_humerus: ArrayLike, sequence: str = "YXY", gimbal_tol: float = np.radians(10.0)
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Thoraco-humeral angles (rad) of the humerus relative to the thorax (Wu 2005 §3.3.4).

    Parameters
    ----------
    R_thorax, R_humerus : array_like, shape (..., 3, 3)
        Segment -> world rotations (columns = ISB axes).
    sequence : {"YXY", "XZY"}
        Intrinsic sequence: Y-X-Y (plane of elevation, elevation as a negative angle in [-π, 0],
        axial rotation) or
        the X-Z-Y alternative (abduction, flexion, axial rotation) recommended near gimbal lock.
    gimbal_tol : float
        Frames whose middle angle is within this of the singular value (0/π for Y-X-Y, ±π/2 for
        X-Z-Y) are flagged.

    Returns
    -------
    angles : ndarray, shape (..., 3)
    near_gimbal_lock : ndarray of bool, shape (...)

    Examples
    --------
    >>> R = Rotation.from_euler("YXY", [0.3, -0.8, 0.2]).as_matrix()
    >>> ang, flag = isb_shoulder_angles(np.eye(3), R)
    >>> ang.round(12).tolist(), bool(flag)
    ([0.3, -0.8, 0.2], False)
    """
    seq = sequence.upper()
    if seq not in ("YXY", "XZY"):
        raise DegenerateJointGeometry(f"shoulder sequence must be 'YXY' or 'XZY', got {sequence!r}")
    ang = _relative_euler(R_thorax, R_humerus, seq)
    if seq == "YXY":
        # scipy returns the middle angle in [0, pi]; ISB reports elevation as a negative rotation
        # about X, i.e. the equivalent solution (a + pi, -b, c + pi).
        pos = ang[..., 1] > 0
        alt = np.stack([ang[..., 0] + np.pi, -ang[..., 1], ang[..., 2] + np.pi], -1)
        alt = np.angle(np.exp(1j * alt))
        ang = np.where(pos[..., None], alt, ang)
    mid = ang[..., 1]
    if seq == "YXY":
        flag = (np.abs(mid) < gimbal_tol) | (np.abs(np.abs(mid) - np.pi) < gimbal_tol)
    else:
        flag = np.abs(np.abs(mid) - np.pi / 2) < gimbal_tol
    return ang, flag


def isb_elbow_angles(R_humerus: ArrayLike, R_forearm: ArrayLike) -> FloatArray:
    """Elbow angles (rad) of the forearm relative to the humerus, intrinsic Z-X-Y (Wu 2005 §3.4.3).

    Returns ``(..., 3)``: flexion (+), carrying angle, pronation (+).

    Examples
    --------
    >>> R = Rotation.from_euler("ZXY", [1.2, 0.1, -0.4]).as_matrix()
    >>> isb_elbow_angles(np.eye(3), R).round(12).tolist()
    [1.2, 0.1, -0.4]
    """
    return _relative_euler(R_humerus, R_forearm, "ZXY")
