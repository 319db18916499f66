"""Moving rigid bodies that carry circular markers: the scenes of the virtual lab.

Every scene answers :meth:`Scene.state` for an array of times: marker centres ``(T, M, 3)`` mm,
marker normals ``(T, M, 3)`` (NaN rows = a spherical marker, seen as a disc facing the viewer),
and the analytic quantities tests compare against. Units: mm, s, rad; right-handed world frame.

Scenes (specs in ``../shared/spec``):

* :class:`RSSRScene`: the RSSR spatial four-bar of ``kinematics.md`` §6 (spherical-joint markers
  ``S_A`` on the input crank and ``S_C`` on the output crank, 0.58 rad/s), positions from
  :func:`~.motion.rssr_motion`.
* :class:`FourBarScene`: the planar four-bar of ``analysis.md`` §4 (230/100/220/133 mm, 20 mm white
  discs: two per moving link, three on the frame).
* :class:`BoxScene`: the 200 x 200 x 300 mm box in free flight (torque-free tumbling from
  :func:`~.motion.torque_free_rotation`, ballistic centre), one spherical marker at each vertex,
  hidden by the box itself when no incident face looks at the viewer.
* :class:`UpperLimbScene`: an arm model with markers P0-P5 lifting a 700 mm bar (``analysis.md`` §8);
  P6 = (P4 + P5) / 2 is given in the analytic quantities.
* :class:`GridScene`: static discs on the calibration plane Z = 0 (see
  :func:`~mirrorlab.instruments.virtual_lab.optics.calibration_grid`).

The motions are the lab's own (:mod:`.motion`), independent of the kinematics plugin they validate.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .motion import (
    THESIS_RSSR,
    THESIS_THETA_DOT,
    RSSRGeometry,
    box_inertia,
    box_vertices,
    rotate,
    rssr_motion,
    torque_free_rotation,
)

__all__ = ["BoxScene", "FourBarScene", "GridScene", "Placement", "RSSRScene", "Scene", "SceneState",
           "UpperLimbScene", "GRAVITY_MM_S2"]

FloatArray = NDArray[np.float64]
GRAVITY_MM_S2 = 9806.65


@dataclass(frozen=True)
class Placement:
    """Rigid placement of a mechanism in the lab: ``world = R @ x + offset`` (mm).

    Examples
    --------
    >>> Placement.from_euler((0.0, 0.0, np.pi / 2), (10.0, 0.0, 0.0)).apply([[1.0, 0.0, 0.0]]).round(12)
    array([[10.,  1.,  0.]])
    """

    R: FloatArray = field(default_factory=lambda: np.eye(3))
    offset: FloatArray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def from_euler(cls, angles_xyz: ArrayLike = (0.0, 0.0, 0.0), offset: ArrayLike = (0.0, 0.0, 0.0)) -> Placement:
        """Rotation ``Rz @ Ry @ Rx`` from angles (rad) about the fixed X, Y, Z axes, then ``offset`` (mm)."""
        ax, ay, az = (float(a) for a in angles_xyz)
        R = (_rot([0, 0, 1], az) @ _rot([0, 1, 0], ay) @ _rot([1, 0, 0], ax))
        return cls(R, np.asarray(offset, dtype=float).reshape(3))

    def apply(self, x: ArrayLike) -> FloatArray:
        """Points ``(..., 3)`` mm in the mechanism frame -> world."""
        return np.asarray(x, dtype=float) @ np.asarray(self.R, float).T + np.asarray(self.offset, float)

    def rotate(self, v: ArrayLike) -> FloatArray:
        """Directions ``(..., 3)`` in the mechanism frame -> world."""
        return np.asarray(v, dtype=float) @ np.asarray(self.R, float).T


def _rot(axis: ArrayLike, angle: float) -> FloatArray:
    return rotate(np.eye(3), axis, angle).T


@dataclass(frozen=True)
class SceneState:
    """Markers of a scene at times ``t``.

    Attributes
    ----------
    t : (T,) s.
    positions : (T, M, 3) marker centres, mm.
    normals : (T, M, 3) unit marker normals; NaN rows for spherical markers.
    analytic : name -> array, the scene's exact quantities (first axis = time).
    """

    t: FloatArray
    positions: FloatArray
    normals: FloatArray
    analytic: dict[str, FloatArray]


class Scene(ABC):
    """Rigid bodies carrying circular markers, moving in time.

    Subclasses set :attr:`name`, :attr:`labels`, :attr:`radii` and implement :meth:`state`.
    """

    name: str = ""
    #: Marker names, one per marker (M).
    labels: tuple[str, ...] = ()
    #: Duration of the motion (s); ``None`` = endless (periodic or static).
    duration: float | None = None

    @property
    @abstractmethod
    def radii(self) -> FloatArray:
        """Marker radii (M,), mm."""

    @abstractmethod
    def state(self, t: ArrayLike) -> SceneState:
        """Positions, normals and analytic quantities at times ``t`` (s)."""

    def positions(self, t: ArrayLike) -> FloatArray:
        """Marker centres ``(T, M, 3)``, mm."""
        return self.state(t).positions

    def occluded(self, state: SceneState, viewpoint: ArrayLike) -> NDArray[np.bool_]:
        """Markers ``(T, M)`` hidden from ``viewpoint`` (mm) by the scene's own bodies (default none)."""
        return np.zeros(state.positions.shape[:2], dtype=bool)


def _times(t: ArrayLike) -> FloatArray:
    return np.atleast_1d(np.asarray(t, dtype=float)).reshape(-1)


def _spheres(T: int, M: int) -> FloatArray:
    return np.full((T, M, 3), np.nan)


# ---------------------------------------------------------------------------------------------- RSSR
@dataclass(frozen=True)
class RSSRScene(Scene):
    """The RSSR spatial four-bar of ``kinematics.md`` §6 driven at a constant crank speed.

    Markers are the spherical joints ``S_A`` (input crank) and ``S_C`` (output crank), as in the
    thesis experiment; they are balls of radius ``marker_radius``. Positions are exactly
    ``placement.apply(rssr_motion(theta0 + theta_dot * t).S_A / S_C)``.

    Analytic quantities: ``theta``, ``theta_dot``, ``theta_ddot`` (rad, rad/s, rad/s²), ``phi``,
    ``phi_dot``, ``phi_ddot`` (signed output angle and its derivatives), ``S_A``, ``S_C`` in the
    mechanism frame (mm).

    Examples
    --------
    >>> s = RSSRScene().state([0.0])
    >>> s.positions[0, 1].round(3).tolist(), round(float(s.analytic["phi_dot"][0]), 6)
    ([-169.63, -120.373, -79.398], 0.227955)
    """

    params: RSSRGeometry = THESIS_RSSR
    theta_dot: float = THESIS_THETA_DOT
    theta0: float = 0.0
    marker_radius: float = 10.0
    placement: Placement = field(default_factory=Placement)
    name: str = "rssr"
    labels: tuple[str, ...] = ("S_A", "S_C")

    @property
    def radii(self) -> FloatArray:
        return np.full(2, float(self.marker_radius))

    def state(self, t: ArrayLike) -> SceneState:
        tt = _times(t)
        theta = self.theta0 + self.theta_dot * tt
        s = rssr_motion(theta, self.theta_dot, 0.0, self.params)
        mech = np.stack([s.S_A, s.S_C], axis=1)
        analytic = {"theta": theta, "theta_dot": np.full_like(tt, self.theta_dot), "theta_ddot": np.zeros_like(tt),
                    "phi": s.phi, "phi_dot": s.phi_dot, "phi_ddot": s.phi_ddot, "S_A": s.S_A, "S_C": s.S_C}
        return SceneState(tt, self.placement.apply(mech), _spheres(tt.size, 2), analytic)


# ---------------------------------------------------------------------------------- planar four-bar
#: Marker offsets (mm) in each link's frame (x along the link from its first joint, y to the left).
FOUR_BAR_MARKERS: dict[str, tuple[tuple[float, float], ...]] = {
    "frame": ((-70.0, -110.0), (110.0, -150.0), (310.0, -140.0)),
    "crank": ((35.0, 12.0), (80.0, -10.0)),
    "coupler": ((95.0, 35.0), (165.0, -20.0)),
    "rocker": ((45.0, 10.0), (100.0, -12.0)),
}


@dataclass(frozen=True)
class FourBarScene(Scene):
    """Planar four-bar (``analysis.md`` §4): ground pivots G1 = (0, 0), G2 = (frame, 0) on z = 0.

    The crank G1-J1 turns at ``omega`` (rad/s) from ``theta0``; the coupler J1-J2 and the rocker
    G2-J2 close the loop (``branch`` +1: J2 on the +y side of the line J1-G2). Links: frame L0 =
    230, input crank L1 = 100, coupler L3 = 220, rocker L4 = 133 mm (Grashof crank-rocker). Markers are
    flat discs of radius ``marker_radius`` (20 mm white markers) with normal +z of the mechanism.

    Analytic quantities: ``theta`` (crank angle), ``psi`` (rocker angle from +x), ``J1``, ``J2``,
    ``G1``, ``G2`` (mechanism frame, mm) and ``lengths`` (L0, L1, L3, L4).

    Examples
    --------
    >>> st = FourBarScene().state(np.linspace(0, 3, 7))
    >>> d = np.linalg.norm(st.analytic["J2"] - st.analytic["J1"], axis=-1)
    >>> bool(np.allclose(d, 220.0))
    True
    """

    frame: float = 230.0
    crank: float = 100.0
    coupler: float = 220.0
    rocker: float = 133.0
    omega: float = 2.0
    theta0: float = 0.0
    branch: int = 1
    marker_radius: float = 10.0
    placement: Placement = field(default_factory=Placement)
    name: str = "four_bar"
    labels: tuple[str, ...] = ("F1", "F2", "F3", "L1a", "L1b", "L3a", "L3b", "L4a", "L4b")

    @property
    def radii(self) -> FloatArray:
        return np.full(len(self.labels), float(self.marker_radius))

    def state(self, t: ArrayLike) -> SceneState:
        tt = _times(t)
        theta = self.theta0 + self.omega * tt
        G1 = np.zeros(2)
        G2 = np.array([self.frame, 0.0])
        J1 = self.crank * np.stack([np.cos(theta), np.sin(theta)], -1)
        # J2: intersection of the circles (J1, coupler) and (G2, rocker)
        dv = G2 - J1
        dist = np.linalg.norm(dv, axis=-1)
        if np.any(dist > self.coupler + self.rocker) or np.any(dist < abs(self.coupler - self.rocker)):
            k = int(np.flatnonzero((dist > self.coupler + self.rocker) | (dist < abs(self.coupler - self.rocker)))[0])
            raise ValueError(f"four-bar cannot close at t = {tt[k]:g} s (theta = {theta[k]:.4g} rad); "
                             "check the link lengths (Grashof crank-rocker needs s + l <= p + q)")
        along = (self.coupler**2 - self.rocker**2 + dist**2) / (2 * dist)
        h = np.sqrt(np.maximum(self.coupler**2 - along**2, 0.0))
        ex = dv / dist[:, None]
        ey = np.stack([-ex[:, 1], ex[:, 0]], -1)
        J2 = J1 + along[:, None] * ex + self.branch * h[:, None] * ey
        psi = np.arctan2(J2[:, 1] - G2[1], J2[:, 0] - G2[0])
        T = tt.size

        def on_link(origin: FloatArray, tip: FloatArray, offsets: tuple[tuple[float, float], ...]) -> FloatArray:
            x = tip - origin
            x = x / np.linalg.norm(x, axis=-1, keepdims=True)
            y = np.stack([-x[..., 1], x[..., 0]], -1)
            o = np.asarray(offsets, float)
            return origin[..., None, :] + o[:, 0, None] * x[..., None, :] + o[:, 1, None] * y[..., None, :]

        fixed = np.broadcast_to(np.asarray(FOUR_BAR_MARKERS["frame"], float), (T, 3, 2))
        pts2 = np.concatenate([
            fixed,
            on_link(np.broadcast_to(G1, J1.shape), J1, FOUR_BAR_MARKERS["crank"]),
            on_link(J1, J2, FOUR_BAR_MARKERS["coupler"]),
            on_link(np.broadcast_to(G2, J2.shape), J2, FOUR_BAR_MARKERS["rocker"]),
        ], axis=1)
        mech = np.concatenate([pts2, np.zeros((T, pts2.shape[1], 1))], -1)
        normals = np.broadcast_to(self.placement.rotate([0.0, 0.0, 1.0]), mech.shape).copy()
        z = np.zeros((T, 1))
        analytic = {"theta": theta, "psi": psi, "J1": np.hstack([J1, z]), "J2": np.hstack([J2, z]),
                    "G1": np.tile([0.0, 0.0, 0.0], (T, 1)), "G2": np.tile([self.frame, 0.0, 0.0], (T, 1)),
                    "lengths": np.tile([self.frame, self.crank, self.coupler, self.rocker], (T, 1))}
        return SceneState(tt, self.placement.apply(mech), normals, analytic)


# ------------------------------------------------------------------------------------ box in flight
@dataclass(frozen=True)
class BoxScene(Scene):
    """The 200 x 200 x 300 mm, 2.2 kg box thrown through the lab (``kinematics.md`` §5).

    Attitude: torque-free rotation from identity with body rate ``omega0_body`` (rad/s), Euler's
    equations integrated by DOP853 (tolerance 1e-12); centre: ``centre0 + velocity0 t + g t² / 2``
    with gravity along -Y (mm/s²). One spherical marker at each vertex; a vertex is hidden from a
    viewpoint when none of its three faces looks at it (the box is convex).

    Analytic quantities: ``R`` (T, 3, 3) body -> world, ``omega_world``, ``omega_body`` (rad/s),
    ``H_world`` (kg·m²/s, constant), ``centre`` (mm), ``velocity`` (mm/s).

    Examples
    --------
    >>> st = BoxScene().state(np.linspace(0.0, 0.5, 6))
    >>> bool(np.allclose(st.analytic["H_world"], [0.0715, 0.0238333, 0.088], atol=1e-6))
    True
    """

    size: tuple[float, float, float] = (200.0, 200.0, 300.0)
    mass: float = 2.2
    omega0_body: tuple[float, float, float] = (3.0, 1.0, 6.0)
    centre0: tuple[float, float, float] = (-450.0, 0.0, 0.0)
    velocity0: tuple[float, float, float] = (1300.0, 3000.0, 0.0)
    gravity: float = GRAVITY_MM_S2
    marker_radius: float = 8.0
    duration: float | None = 0.6
    name: str = "box"
    labels: tuple[str, ...] = tuple(f"V{i}" for i in range(8))

    @property
    def radii(self) -> FloatArray:
        return np.full(8, float(self.marker_radius))

    @property
    def vertices(self) -> FloatArray:
        """Body-frame vertex coordinates (8, 3), mm (signs ``(±x, ±y, ±z)``, x outermost)."""
        return box_vertices(self.size)

    def state(self, t: ArrayLike) -> SceneState:
        tt = _times(t)
        grid, inverse = np.unique(np.concatenate([[0.0], tt]), return_inverse=True)
        if grid[0] < 0:
            raise ValueError(f"box scene times must be >= 0 s (got {grid[0]:g} s)")
        inertia = box_inertia(self.mass, np.asarray(self.size) / 1000.0)
        if grid.size == 1:
            R = np.eye(3)[None]
            wb = np.asarray(self.omega0_body, float)[None]
        else:
            R, wb = torque_free_rotation(inertia, self.omega0_body, grid)
        sel = inverse[1:]
        R, wb = R[sel], wb[sel]
        ww = np.einsum("tij,tj->ti", R, wb)
        H = np.einsum("tij,tj->ti", R, inertia * wb)
        g = np.array([0.0, -self.gravity, 0.0])
        c0, v0 = np.asarray(self.centre0, float), np.asarray(self.velocity0, float)
        centre = c0 + tt[:, None] * v0 + 0.5 * tt[:, None] ** 2 * g
        velocity = v0 + tt[:, None] * g
        pos = np.einsum("tij,mj->tmi", R, self.vertices) + centre[:, None]
        analytic = {"R": R, "omega_world": ww, "omega_body": wb, "H_world": H, "centre": centre,
                    "velocity": velocity}
        return SceneState(tt, pos, _spheres(tt.size, 8), analytic)

    def occluded(self, state: SceneState, viewpoint: ArrayLike) -> NDArray[np.bool_]:
        """A vertex is hidden when all three faces meeting at it face away from ``viewpoint``."""
        R = state.analytic["R"]
        to_view = np.asarray(viewpoint, float) - state.positions                      # (T, 8, 3)
        local = np.einsum("tji,tmj->tmi", R, to_view)                                  # body frame
        signs = np.sign(self.vertices)                                                 # outward face normals
        return ~np.any(local * signs[None] > 0, axis=-1)


# --------------------------------------------------------------------------------------- upper limb
@dataclass(frozen=True)
class UpperLimbScene(Scene):
    """A right arm lifting a 700 mm bar (``analysis.md`` §8), world X forward, Y up, Z to the right.

    Forward kinematics from prescribed joint drives (rad), each ``mean + amp sin(2 pi t / period +
    phase)``: shoulder flexion ``alpha`` (about Z), abduction ``beta``, humeral rotation ``gamma``,
    elbow flexion ``epsilon``, pronation ``rho``, wrist flexion ``delta``. The elbow lags the shoulder,
    so elbow and wrist paths form out-and-back loops. The trunk (P0) sways fore-aft by
    ``trunk_sway`` mm and the acromion (P1) rises with the flexion (clavicle elevation).

    Markers: P0 manubrium, P1 acromion, P2 elbow, P3 wrist, P4 / P5 bar ends (P5 thumb side). The
    analytic quantities hold the drives, ``P6 = (P4 + P5) / 2`` and the elbow angle
    ``theta3 = epsilon`` (angle between P1P2 and P2P3, eq. 6.7).

    Examples
    --------
    >>> st = UpperLimbScene().state(np.linspace(0, 2, 5))
    >>> float(np.linalg.norm(st.positions[:, 5] - st.positions[:, 4], axis=-1).max().round(9))
    700.0
    """

    upper_arm: float = 300.0
    forearm: float = 260.0
    hand: float = 80.0
    bar: float = 700.0
    period: float = 2.5
    trunk_sway: float = 25.0
    shoulder_height: float = 1400.0
    marker_radius: float = 10.0
    # (mean, amplitude, phase) per drive
    alpha: tuple[float, float, float] = (0.55, 0.45, 0.0)
    beta: tuple[float, float, float] = (0.15, 0.05, 0.3)
    gamma: tuple[float, float, float] = (0.10, 0.10, 0.5)
    epsilon: tuple[float, float, float] = (1.10, 0.45, -0.6)
    rho: tuple[float, float, float] = (0.30, 0.10, 0.2)
    delta: tuple[float, float, float] = (0.05, 0.20, 1.2)
    name: str = "upper_limb"
    labels: tuple[str, ...] = ("P0", "P1", "P2", "P3", "P4", "P5")

    @property
    def radii(self) -> FloatArray:
        return np.full(6, float(self.marker_radius))

    def drives(self, t: ArrayLike) -> dict[str, FloatArray]:
        """The prescribed joint angles (rad) at times ``t``."""
        w = 2 * np.pi * _times(t) / self.period
        return {k: m + a * np.sin(w + p) for k, (m, a, p) in
                (("alpha", self.alpha), ("beta", self.beta), ("gamma", self.gamma),
                 ("epsilon", self.epsilon), ("rho", self.rho), ("delta", self.delta))}

    def state(self, t: ArrayLike) -> SceneState:
        tt = _times(t)
        d = self.drives(tt)
        w = 2 * np.pi * tt / self.period
        T = tt.size
        X, Y, Z = np.eye(3)
        P0 = np.stack([self.trunk_sway * np.sin(w - 0.4), np.full(T, self.shoulder_height), np.zeros(T)], -1)
        elevation = 15.0 * (d["alpha"] - self.alpha[0])
        P1 = P0 + np.stack([np.full(T, -30.0), 20.0 + elevation, np.full(T, 170.0)], -1)

        def R(axis: FloatArray, angle: FloatArray) -> FloatArray:   # (T, 3, 3) rotation matrices
            return np.stack([rotate(e, axis, angle) for e in np.eye(3)], -1)

        R_ua = R(Z, d["alpha"]) @ R(X, d["beta"]) @ R(Y, d["gamma"])
        P2 = P1 + R_ua @ np.array([0.0, -self.upper_arm, 0.0])
        R_fa = R_ua @ R(Z, d["epsilon"])
        P3 = P2 + R_fa @ np.array([0.0, -self.forearm, 0.0])
        R_h = R_fa @ R(Y, d["rho"]) @ R(Z, d["delta"])
        P6 = P3 + R_h @ np.array([0.0, -self.hand, 0.0])
        axis = R_h @ Z
        P4 = P6 - 0.5 * self.bar * axis
        P5 = P6 + 0.5 * self.bar * axis
        pos = np.stack([P0, P1, P2, P3, P4, P5], axis=1)
        analytic = {**d, "P6": P6, "theta3": d["epsilon"].copy()}
        return SceneState(tt, pos, _spheres(T, 6), analytic)


# ------------------------------------------------------------------------------ calibration grid
@dataclass(frozen=True)
class GridScene(Scene):
    """Static flat discs at ``points`` (N, 3) mm, normal +Z: the planar calibration grid.

    Examples
    --------
    >>> g = GridScene(np.array([[0.0, 0.0, 0.0], [60.0, 0.0, 0.0]]))
    >>> g.positions([0.0, 1.0]).shape
    (2, 2, 3)
    """

    points: FloatArray = field(default_factory=lambda: np.zeros((1, 3)))
    marker_radius: float = 8.0
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)
    name: str = "grid"

    @property
    def labels(self) -> tuple[str, ...]:  # type: ignore[override]
        return tuple(f"G{i}" for i in range(len(self.points)))

    @property
    def radii(self) -> FloatArray:
        return np.full(len(self.points), float(self.marker_radius))

    def state(self, t: ArrayLike) -> SceneState:
        tt = _times(t)
        p = np.asarray(self.points, float).reshape(-1, 3)
        pos = np.broadcast_to(p, (tt.size, *p.shape)).copy()
        n = np.asarray(self.normal, float) / np.linalg.norm(self.normal)
        return SceneState(tt, pos, np.broadcast_to(n, pos.shape).copy(), {"points": pos.copy()})
