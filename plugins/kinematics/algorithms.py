"""Algorithm adapters of the kinematics functions.

Each algorithm is a thin class around the pure functions of this package: it reads arrays, calls
one function, and returns arrays. Units: mm, s, rad (angular velocity rad/s, inertia kg·m²,
angular momentum kg·m²/s).

=====================  ==========================================  ===============================
algorithm              inputs                                      outputs
=====================  ==========================================  ===============================
``derivatives``        time (T,), values (T, ...)                  smoothed, velocity, acceleration
``filter``             time (T,), values (T, ...)                  time, filtered, cutoff
``rigid_body_motion``  time, markers (T, M, 3) [, reference]       R, origin, omega, rms, n_visible,
                                                                   reference
``angular_momentum``   time + markers [+ reference], or R + omega  H, H_norm, H_variation, omega, R
                       [, inertia]
``rssr_angles``        time, S_A (T, 3), S_C (T, 3)                theta, phi and derivatives,
                                                                   model_phi/_dot/_ddot
``upper_limb_angles``  P0..P3 (T, 3) [, P4, P5]                    theta0..theta6 + signed forms
``isb_angles``         GH, EL, EM [, IJ, PX, C7, T8] [, US, RS]    shoulder, near_gimbal_lock, elbow
=====================  ==========================================  ===============================
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext

from .derivatives import derivatives
from .errors import KinematicsError
from .filters import butterworth, fill_gaps, residual_cutoff, smoothing_spline, thesis_filter
from .joint_angles import (
    isb_elbow_angles,
    isb_forearm_frame,
    isb_humerus_frame,
    isb_shoulder_angles,
    isb_thorax_frame,
    upper_limb_angles,
)
from .rigid import angular_momentum, rigid_body_motion
from .rssr import THESIS_RSSR, RSSRParams, rssr_angles_from_markers, rssr_state
from .synthetic import box_inertia

if TYPE_CHECKING:
    pass


class KinematicsParameterError(KinematicsError):
    """A parameter or optional input of a kinematics algorithm is unusable (vector text, inertia...)."""


# ------------------------------------------------------------------------------------------------
# shared parameter groups
# ------------------------------------------------------------------------------------------------
GAP_PARAMETERS = (
    Parameter("max_gap", int, 0, bounds=(0, None),
              help="bridge interior NaN gaps of at most this many samples by a cubic spline (0: never)"),
    Parameter("max_gap_s", float, 0.0, unit="s", bounds=(0.0, None),
              help="bridge interior gaps spanning at most this time (0: no time limit; both limits apply)"),
)

DERIVATIVE_PARAMETERS = (
    Parameter("method", str, "smoothing_spline", choices=("smoothing_spline", "thesis_spline", "butterworth"),
              help="differentiation method: GCV smoothing spline, thesis 1-2-3-3-2-1 filter + parametric "
                   "spline, or zero-phase Butterworth + central differences"),
    Parameter("lam", float, -1.0, bounds=(-1.0, None),
              help="smoothing spline: regularisation (value²·s³); -1 chooses it by GCV per channel, "
                   "0 gives the interpolating natural spline"),
    Parameter("prefilter", bool, True,
              help="thesis spline: apply the 1-2-3-3-2-1 filter before each spline (needs uniform sampling)"),
    Parameter("cutoff", float, 6.0, unit="Hz", bounds=(0.01, None), help="Butterworth cut-off frequency"),
    Parameter("cutoff_method", str, "fixed", choices=("fixed", "residual"),
              help="Butterworth: use --cutoff, or choose it per channel by Winter's residual analysis"),
    Parameter("order", int, 2, bounds=(1, 8), help="Butterworth order of one pass (zero-phase doubles it)"),
) + GAP_PARAMETERS


def gap_kwargs(params: Mapping[str, Any]) -> dict[str, Any]:
    """``max_gap`` / ``max_gap_s`` keyword arguments (only the limits that are set)."""
    out: dict[str, Any] = {}
    if params.get("max_gap"):
        out["max_gap"] = int(params["max_gap"])
    if params.get("max_gap_s"):
        out["max_gap_s"] = float(params["max_gap_s"])
    return out


def derivative_kwargs(params: Mapping[str, Any]) -> tuple[str, dict[str, Any]]:
    """``(method, kwargs)`` for :func:`~.derivatives.derivatives` from validated parameters.

    Examples
    --------
    >>> derivative_kwargs({"method": "butterworth", "cutoff": 8.0, "cutoff_method": "fixed", "order": 2,
    ...                    "max_gap": 3, "max_gap_s": 0.0})
    ('butterworth', {'max_gap': 3, 'cutoff': 8.0, 'order': 2})
    """
    method = params["method"]
    kw = gap_kwargs(params)
    if method == "smoothing_spline":
        if params.get("lam", -1.0) >= 0:
            kw["lam"] = float(params["lam"])
    elif method == "thesis_spline":
        kw["prefilter"] = bool(params.get("prefilter", True))
    elif method == "butterworth":
        kw["cutoff"] = "residual" if params.get("cutoff_method") == "residual" else float(params["cutoff"])
        kw["order"] = int(params["order"])
    return method, kw


def _as_float(inputs: Mapping[str, np.ndarray], name: str) -> np.ndarray:
    return np.asarray(inputs[name], dtype=float)


def _points(inputs: Mapping[str, np.ndarray], name: str, n: int | None = None) -> np.ndarray:
    p = _as_float(inputs, name)
    if p.ndim != 2 or p.shape[1] != 3 or (n is not None and p.shape[0] != n):
        want = f"({n}, 3)" if n is not None else "(T, 3)"
        raise KinematicsParameterError(f"input {name} must be a marker trajectory of shape {want}, got {p.shape}")
    return p


def channel_chunks(shape: tuple[int, ...], target: int = 40) -> list[slice]:
    """Column slices of ``values.reshape(T, -1)`` that keep each marker's x, y, z together."""
    width = int(np.prod(shape[1:])) if len(shape) > 1 else 1
    unit = shape[-1] if len(shape) > 1 else 1
    per = max(unit, unit * int(np.ceil(width / unit / target)))
    return [slice(a, min(a + per, width)) for a in range(0, width, per)]


def chunked(fn: Callable[[np.ndarray], tuple[np.ndarray, ...]], values: np.ndarray, context: RunContext,
            message: str) -> tuple[np.ndarray, ...]:
    """Apply ``fn`` (time along axis 0, channels independent) to column chunks, reporting progress."""
    T = values.shape[0]
    flat = values.reshape(T, -1)
    chunks = channel_chunks(values.shape)
    outs: list[np.ndarray] | None = None
    for k, sl in enumerate(chunks):
        context.progress(k, len(chunks), message)
        res = fn(flat[:, sl])
        if outs is None:
            outs = [np.full((r.shape[0], flat.shape[1]), np.nan) for r in res]
        for o, r in zip(outs, res, strict=True):
            o[:, sl] = r.reshape(r.shape[0], -1)
    context.progress(len(chunks), len(chunks), "done")
    assert outs is not None
    return tuple(o.reshape((o.shape[0],) + values.shape[1:]) for o in outs)


# ------------------------------------------------------------------------------------------------
# algorithms
# ------------------------------------------------------------------------------------------------
class Derivatives(Algorithm):
    """Smoothed positions, velocities and accelerations of any sampled signal (time on axis 0)."""

    name = "derivatives"
    version = "0.2.0"
    description = "smoothed values, velocity and acceleration (thesis spline, smoothing spline, Butterworth)"
    parameters = ParameterSet(*DERIVATIVE_PARAMETERS)
    inputs = (Port("time", "(T,) sample times", "s"),
              Port("values", "(T, ...) samples, e.g. markers (T, M, 3); NaN where missing"))
    outputs = (Port("smoothed", "(T, ...) smoothed values", "{values}"),
               Port("velocity", "(T, ...) first derivative", "{values}/s"),
               Port("acceleration", "(T, ...) second derivative", "{values}/s²"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        t = _as_float(inputs, "time")
        x = _as_float(inputs, "values")
        method, kw = derivative_kwargs(params)
        if x.ndim == 1:
            context.progress(0, 1, method)
            smoothed, velocity, acceleration = derivatives(t, x, method, **kw)
            context.progress(1, 1, "done")
        else:
            smoothed, velocity, acceleration = chunked(lambda c: derivatives(t, c, method, **kw), x, context, method)
        return {"smoothed": smoothed, "velocity": velocity, "acceleration": acceleration}


class Filter(Algorithm):
    """Low-pass filter of a sampled signal: thesis 1-2-3-3-2-1, zero-phase Butterworth, smoothing spline."""

    name = "filter"
    version = "0.1.0"
    description = "low-pass filter (thesis 1-2-3-3-2-1 /12, zero-phase Butterworth, GCV smoothing spline)"
    parameters = ParameterSet(
        Parameter("method", str, "thesis", choices=("thesis", "butterworth", "smoothing_spline"),
                  help="thesis: eq. 3.21 (output 5 samples shorter, centred at t+2.5T); butterworth: "
                       "scipy butter + sosfiltfilt; smoothing_spline: make_smoothing_spline"),
        *DERIVATIVE_PARAMETERS[1:2], *DERIVATIVE_PARAMETERS[3:6], *GAP_PARAMETERS,
    )
    inputs = (Port("time", "(T,) sample times", "s"), Port("values", "(T, ...) samples, NaN where missing"))
    outputs = (Port("time", "(T',) times of the filtered samples (thesis: T' = T - 5, t_k + 2.5 T)", "s"),
               Port("filtered", "(T', ...) filtered samples, NaN where missing", "{values}"),
               Port("cutoff", "(...) Butterworth cut-off per channel (NaN for the other methods)", "Hz"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        t = _as_float(inputs, "time")
        x = _as_float(inputs, "values")
        gaps = gap_kwargs(params)
        cutoff = np.full(x.shape[1:], np.nan)
        context.progress(0, 1, params["method"])
        if params["method"] == "thesis":
            tau, h = thesis_filter(t, fill_gaps(t, x, **gaps) if gaps else x)
        elif params["method"] == "butterworth":
            tau = t
            if params["cutoff_method"] == "residual":
                cutoff = residual_cutoff(t, fill_gaps(t, x, **gaps) if gaps else x, order=params["order"])
                h = butterworth(t, x, cutoff="residual", order=params["order"], **gaps)
            else:
                cutoff[...] = params["cutoff"]
                h = butterworth(t, x, cutoff=params["cutoff"], order=params["order"], **gaps)
        else:
            tau = t
            h = smoothing_spline(t, x, lam=params["lam"] if params["lam"] >= 0 else None, **gaps)
        context.progress(1, 1, "done")
        return {"time": tau, "filtered": h, "cutoff": cutoff}


class RigidBodyMotionAlgorithm(Algorithm):
    """Least-squares pose (Kabsch) and world-frame angular velocity of a rigid marker cluster."""

    name = "rigid_body_motion"
    version = "0.1.0"
    description = "pose R, origin and angular velocity omega of a rigid cluster of >= 3 markers (gaps allowed)"
    parameters = ParameterSet(*DERIVATIVE_PARAMETERS)
    inputs = (Port("time", "(T,) frame times", "s"),
              Port("markers", "(T, M >= 3, 3) marker positions, NaN where missing", "mm"),
              Port("reference", "(M, 3) body-fixed marker coordinates (default: mean layout, centroid "
                                "origin, world axes at the first complete frame)", "mm", optional=True))
    outputs = (Port("R", "(T, 3, 3) body-to-world rotation (NaN if < 3 markers visible)"),
               Port("origin", "(T, 3) world position of the body origin", "mm"),
               Port("omega", "(T, 3) angular velocity, world frame", "rad/s"),
               Port("rms", "(T,) rigid-fit residual", "mm"),
               Port("n_visible", "(T,) markers used per frame"),
               Port("reference", "(M, 3) body-fixed marker coordinates used", "mm"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        method, kw = derivative_kwargs(params)
        context.progress(0, 1, "fitting poses")
        rb = rigid_body_motion(_as_float(inputs, "time"), _as_float(inputs, "markers"),
                               reference=inputs.get("reference"), method=method, **kw)
        context.progress(1, 1, "done")
        return {"R": rb.R, "origin": rb.origin, "omega": rb.omega, "rms": rb.rms, "n_visible": rb.n_visible,
                "reference": rb.reference}


INERTIA_PARAMETERS = (
    Parameter("Ixx", float, 0.0, help="inertia tensor about the centre of mass, body axes of the reference (kg·m²)"),
    Parameter("Iyy", float, 0.0, help="inertia tensor element (kg·m²)"),
    Parameter("Izz", float, 0.0, help="inertia tensor element (kg·m²)"),
    Parameter("Ixy", float, 0.0, help="product of inertia (kg·m², tensor convention: I = ∫(r²E - r rᵀ) dm)"),
    Parameter("Ixz", float, 0.0, help="product of inertia (kg·m²)"),
    Parameter("Iyz", float, 0.0, help="product of inertia (kg·m²)"),
    Parameter("mass", float, 0.0, bounds=(0.0, None),
              help="kg; with box_x/y/z: use the inertia of a uniform box instead of Ixx..Iyz"),
    Parameter("box_x", float, 0.0, unit="mm", bounds=(0.0, None), help="uniform box edge along body x"),
    Parameter("box_y", float, 0.0, unit="mm", bounds=(0.0, None), help="uniform box edge along body y"),
    Parameter("box_z", float, 0.0, unit="mm", bounds=(0.0, None), help="uniform box edge along body z"),
    Parameter("trim", int, 0, bounds=(0, None),
              help="frames left out at each end when computing H_variation (spline end effects)"),
)


def inertia_tensor(params: Mapping[str, Any], given: np.ndarray | None = None) -> np.ndarray:
    """Body-frame inertia (3, 3) kg·m²: the ``inertia`` input, else a uniform box, else Ixx..Iyz.

    Raises
    ------
    KinematicsParameterError
        Nothing given, wrong shape, or not symmetric positive definite.

    Examples
    --------
    >>> inertia_tensor({"mass": 2.2, "box_x": 200.0, "box_y": 200.0, "box_z": 300.0}).diagonal().round(7).tolist()
    [0.0238333, 0.0238333, 0.0146667]
    """
    if given is not None:
        I = np.asarray(given, dtype=float)
        I = np.diag(I) if I.shape == (3,) else I
        source = "input inertia"
    elif params.get("mass", 0.0) > 0:
        size = np.array([params.get("box_x", 0.0), params.get("box_y", 0.0), params.get("box_z", 0.0)])
        if np.any(size <= 0):
            raise KinematicsParameterError("mass is set: give all three box edges box_x, box_y, box_z (mm) > 0")
        I = np.diag(box_inertia(params["mass"], size / 1000.0))
        source = "box"
    else:
        g = {k: float(params.get(k, 0.0)) for k in ("Ixx", "Iyy", "Izz", "Ixy", "Ixz", "Iyz")}
        I = np.array([[g["Ixx"], g["Ixy"], g["Ixz"]], [g["Ixy"], g["Iyy"], g["Iyz"]], [g["Ixz"], g["Iyz"], g["Izz"]]])
        source = "Ixx..Iyz"
        if not np.any(I):
            raise KinematicsParameterError("no inertia given: set Ixx, Iyy, Izz (kg·m²), or mass and box_x/y/z, "
                                           "or pass an 'inertia' input")
    if I.shape != (3, 3) or not np.allclose(I, I.T) or np.any(np.linalg.eigvalsh(0.5 * (I + I.T)) <= 0):
        raise KinematicsParameterError(f"{source} must be a symmetric positive-definite 3x3 tensor (kg·m²), "
                                       f"got {I.tolist()}")
    return I


class AngularMomentum(Algorithm):
    """Angular momentum about the centre of mass, eqs (3.45)-(3.48): H_G = R I Rᵀ ω (world frame)."""

    name = "angular_momentum"
    version = "0.1.0"
    description = "angular momentum H_G (world frame) of a rigid body from markers or from R and omega"
    parameters = ParameterSet(*INERTIA_PARAMETERS, *DERIVATIVE_PARAMETERS)
    inputs = (Port("time", "(T,) frame times (with markers)", "s", optional=True),
              Port("markers", "(T, M >= 3, 3) marker positions; the reference origin must be the centre of "
                              "mass", "mm", optional=True),
              Port("reference", "(M, 3) body-fixed marker coordinates, axes = inertia axes", "mm", optional=True),
              Port("R", "(T, 3, 3) body-to-world rotation (instead of markers)", optional=True),
              Port("omega", "(T, 3) world angular velocity (instead of markers)", "rad/s", optional=True),
              Port("inertia", "(3,) principal or (3, 3) body-frame inertia tensor (overrides parameters)",
                   "kg·m²", optional=True))
    outputs = (Port("H", "(T, 3) angular momentum about G, world frame", "kg·m²/s"),
               Port("H_norm", "(T,) |H_G|", "kg·m²/s"),
               Port("H_variation", "(max - min) / mean of |H_G| over the finite frames (minus trim at each end)"),
               Port("omega", "(T, 3) angular velocity, world frame", "rad/s"),
               Port("R", "(T, 3, 3) body-to-world rotation"),
               Port("inertia", "(3, 3) body-frame inertia used", "kg·m²"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        I = inertia_tensor(params, inputs.get("inertia"))
        if "markers" in inputs:
            if "time" not in inputs:
                raise KinematicsParameterError("the markers input needs the time input (frame times in s)")
            method, kw = derivative_kwargs(params)
            context.progress(0, 2, "rigid-body motion")
            rb = rigid_body_motion(_as_float(inputs, "time"), _as_float(inputs, "markers"),
                                   reference=inputs.get("reference"), method=method, **kw)
            R, omega = rb.R, rb.omega
        elif "R" in inputs and "omega" in inputs:
            R, omega = _as_float(inputs, "R"), _as_float(inputs, "omega")
            if R.shape[-2:] != (3, 3) or omega.shape != R.shape[:-1]:
                raise KinematicsParameterError(f"R {R.shape} and omega {omega.shape} must be (T, 3, 3) and (T, 3)")
        else:
            raise KinematicsParameterError("give either time + markers (+ reference) or R + omega "
                                           "(e.g. from a rigid_body_motion result)")
        context.progress(1, 2, "angular momentum")
        H = angular_momentum(np.swapaxes(R, -1, -2), I, omega)
        n = np.linalg.norm(H, axis=-1)
        inner = n[params["trim"]:n.size - params["trim"]]
        fin = inner[np.isfinite(inner)]
        variation = float(np.ptp(fin) / fin.mean()) if fin.size and fin.mean() > 0 else float("nan")
        context.progress(2, 2, "done")
        return {"H": H, "H_norm": n, "H_variation": variation, "omega": omega, "R": R, "inertia": I}


_T = THESIS_RSSR


class RSSRAngles(Algorithm):
    """Measured RSSR input/output angles from the spherical-joint markers, with the analytic model."""

    name = "rssr_angles"
    version = "0.1.0"
    description = "RSSR four-bar: measured theta, phi and derivatives from S_A, S_C markers vs the model (3.39-3.44)"
    parameters = ParameterSet(
        Parameter("O_A", float, _T.O_A, unit="mm", shape=(3,), help="input pivot x, y, z"),
        Parameter("e", float, _T.e, shape=(3,), help="input axis direction x, y, z"),
        Parameter("a0", float, _T.a0, unit="mm", shape=(3,), help="crank vector O_A->S_A at theta = 0, x, y, z"),
        Parameter("d", float, _T.d, unit="mm", shape=(3,), help="vector O_A->O_C, x, y, z"),
        Parameter("f", float, _T.f, shape=(3,), help="output axis direction x, y, z"),
        Parameter("b", float, _T.b, unit="mm", bounds=(0.0, None), help="coupler length"),
        Parameter("c", float, _T.c, unit="mm", bounds=(0.0, None), help="output crank length"),
        Parameter("c1", float, _T.c1, bounds=(-1.0, 1.0), help="c_hat . f_hat (0: crank perpendicular to its axis)"),
        Parameter("branch", int, _T.branch, choices=(1, -1), help="assembly branch of (3.39)"),
        *DERIVATIVE_PARAMETERS,
    )
    inputs = (Port("time", "(T,) frame times", "s"),
              Port("S_A", "(T, 3) input-crank spherical joint", "mm"),
              Port("S_C", "(T, 3) output-crank spherical joint", "mm"))
    outputs = (Port("theta", "(T,) measured input angle (unwrapped)", "rad"),
               Port("theta_dot", "(T,) measured input velocity", "rad/s"),
               Port("theta_ddot", "(T,) measured input acceleration", "rad/s²"),
               Port("phi", "(T,) measured output angle (unwrapped)", "rad"),
               Port("phi_dot", "(T,) measured output velocity", "rad/s"),
               Port("phi_ddot", "(T,) measured output acceleration", "rad/s²"),
               Port("model_phi", "(T,) model output angle at the measured theta", "rad"),
               Port("model_phi_dot", "(T,) model (3.42) with the measured theta_dot", "rad/s"),
               Port("model_phi_ddot", "(T,) model (3.43)-(3.44) with measured theta_dot, theta_ddot", "rad/s²"))

    @staticmethod
    def geometry(params: Mapping[str, Any]) -> RSSRParams:
        return RSSRParams(*(tuple(params[k]) for k in ("O_A", "e", "a0", "d", "f")), params["b"], params["c"], params["c1"],
                          params["branch"])

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        geo = self.geometry(params)
        t = _as_float(inputs, "time")
        S_A, S_C = _points(inputs, "S_A", t.size), _points(inputs, "S_C", t.size)
        method, kw = derivative_kwargs(params)
        context.progress(0, 3, "angles")
        theta, phi = rssr_angles_from_markers(S_A, S_C, geo)
        context.progress(1, 3, "derivatives")
        _, th_d, th_dd = derivatives(t, theta, method, **kw)
        _, ph_d, ph_dd = derivatives(t, phi, method, **kw)
        context.progress(2, 3, "model")
        model = np.full((3, t.size), np.nan)
        ok = np.isfinite(theta) & np.isfinite(th_d) & np.isfinite(th_dd)
        if np.any(ok):
            s = rssr_state(theta[ok], th_d[ok], th_dd[ok], geo)
            model[:, ok] = s.phi, s.phi_dot, s.phi_ddot
            # the model's phi is wrapped to (-pi, pi]; follow the measured revolutions
            model[0, ok] += 2 * np.pi * np.round((phi[ok] - model[0, ok]) / (2 * np.pi))
        context.progress(3, 3, "done")
        return {"theta": theta, "theta_dot": th_d, "theta_ddot": th_dd, "phi": phi, "phi_dot": ph_d,
                "phi_ddot": ph_dd, "model_phi": model[0], "model_phi_dot": model[1], "model_phi_ddot": model[2]}


UPPER_LIMB_OUTPUTS = ("theta0", "theta1", "theta2", "theta3", "theta4", "theta5", "theta6",
                      "theta0s", "theta1s", "phi12", "theta4s", "theta5s", "theta6s")
_ANGLE_HELP = {
    "theta0": "(6.4) flexion, literal (pi for a hanging arm)", "theta1": "(6.5) abduction, literal",
    "theta2": "(6.6) humeral rotation, arcsin(t1.t2)", "theta3": "(6.7) elbow flexion, 0 = straight",
    "theta4": "(6.8) pronation/supination, unsigned", "theta5": "(6.9) palmar/dorsal flexion, literal",
    "theta6": "(6.10) ulnar/radial deviation as printed", "theta0s": "signed flexion (+ forward)",
    "theta1s": "signed abduction", "phi12": "signed twist of plane P1P2P3 from plane P0P1P2",
    "theta4s": "signed forearm twist minus pronation_offset", "theta5s": "signed palmar/dorsal flexion",
    "theta6s": "signed ulnar/radial deviation",
}


class UpperLimbAnglesAlgorithm(Algorithm):
    """Thesis upper-limb angles θ0-θ6 (eqs 6.4-6.10) and their signed variants (analysis.md §8)."""

    name = "upper_limb_angles"
    version = "0.1.0"
    description = "upper-limb joint angles theta0-theta6 (thesis 6.4-6.10) and signed variants from P0..P5"
    parameters = ParameterSet(
        Parameter("side", str, "right", choices=("right", "left"), help="arm side (sign of flexion)"),
        Parameter("vertical", float, (0.0, 1.0, 0.0), shape=(3,),
                  help="laboratory up direction x, y, z (thesis: Y up; C3D often Z up)"),
        Parameter("pronation_offset", float, 0.0, unit="rad", bounds=(-np.pi, np.pi),
                  help="subtracted from theta4s (pi/2: the mid, thumb-up grip reads 0)"),
        Parameter("on_degenerate", str, "nan", choices=("nan", "raise"),
                  help="undefined posture in a frame: NaN there, or fail naming angle and frame"),
    )
    inputs = (Port("P0", "(T, 3) manubrium (trunk reference)", "mm"), Port("P1", "(T, 3) acromion", "mm"),
              Port("P2", "(T, 3) elbow", "mm"), Port("P3", "(T, 3) wrist", "mm"),
              Port("P4", "(T, 3) bar end (hand angles need P4 and P5)", "mm", optional=True),
              Port("P5", "(T, 3) thumb-side bar end", "mm", optional=True))
    outputs = tuple(Port(n, f"(T,) {_ANGLE_HELP[n]}", "rad") for n in UPPER_LIMB_OUTPUTS)

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        n = _points(inputs, "P0").shape[0]
        P = [_points(inputs, f"P{k}", n) for k in range(4)]
        hand = [_points(inputs, k, n) if k in inputs else None for k in ("P4", "P5")]
        if (hand[0] is None) != (hand[1] is None):
            raise KinematicsParameterError("the hand angles need both bar ends P4 and P5; give both or neither")
        context.progress(0, 1, "angles")
        ang = upper_limb_angles(*P, *hand, side=params["side"], vertical=np.asarray(params["vertical"]),
                                pronation_offset=params["pronation_offset"], on_degenerate=params["on_degenerate"])
        context.progress(1, 1, "done")
        return {k: getattr(ang, k) for k in UPPER_LIMB_OUTPUTS}


class ISBAngles(Algorithm):
    """ISB joint coordinate systems (Wu et al. 2005): thoraco-humeral and elbow angles."""

    name = "isb_angles"
    version = "0.1.0"
    description = "ISB shoulder (Y-X-Y or X-Z-Y) and elbow (Z-X-Y) angles from bony landmarks (Wu et al. 2005)"
    parameters = ParameterSet(
        Parameter("side", str, "right", choices=("right", "left"), help="arm side"),
        Parameter("shoulder_sequence", str, "YXY", choices=("YXY", "XZY"),
                  help="thoraco-humeral sequence (X-Z-Y is the ISB alternative near gimbal lock)"),
        Parameter("gimbal_tol", float, float(np.radians(10.0)), unit="rad", bounds=(0.0, np.pi / 2),
                  help="flag frames whose middle shoulder angle is this close to the singular value"),
    )
    inputs = (Port("GH", "(T, 3) glenohumeral rotation centre", "mm"),
              Port("EL", "(T, 3) lateral epicondyle", "mm"), Port("EM", "(T, 3) medial epicondyle", "mm"),
              Port("IJ", "(T, 3) incisura jugularis (shoulder angles need IJ, PX, C7, T8)", "mm", optional=True),
              Port("PX", "(T, 3) processus xiphoideus", "mm", optional=True),
              Port("C7", "(T, 3) 7th cervical vertebra", "mm", optional=True),
              Port("T8", "(T, 3) 8th thoracic vertebra", "mm", optional=True),
              Port("US", "(T, 3) ulnar styloid (elbow angles need US and RS)", "mm", optional=True),
              Port("RS", "(T, 3) radial styloid", "mm", optional=True))
    outputs = (Port("shoulder", "(T, 3) humerus relative to thorax in shoulder_sequence (NaN without thorax)", "rad"),
               Port("near_gimbal_lock", "(T,) shoulder frames near the sequence's singularity"),
               Port("elbow", "(T, 3) Z-X-Y: flexion, carrying angle, pronation (NaN without US, RS)", "rad"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        GH = _points(inputs, "GH")
        n = GH.shape[0]
        EL, EM = _points(inputs, "EL", n), _points(inputs, "EM", n)
        thorax = [k for k in ("IJ", "PX", "C7", "T8") if k in inputs]
        forearm = [k for k in ("US", "RS") if k in inputs]
        if len(thorax) not in (0, 4) or len(forearm) not in (0, 2) or not (thorax or forearm):
            raise KinematicsParameterError(
                "give all of IJ, PX, C7, T8 for the shoulder angles and/or both US, RS for the elbow angles "
                f"(got {', '.join(thorax + forearm) or 'neither'})")
        context.progress(0, 1, "segment frames")
        R_h = isb_humerus_frame(GH, EL, EM, side=params["side"])
        shoulder, flag = np.full((n, 3), np.nan), np.zeros(n, bool)
        elbow = np.full((n, 3), np.nan)
        if thorax:
            ij, px, c7, t8 = (_points(inputs, k, n) for k in ("IJ", "PX", "C7", "T8"))
            shoulder, flag = isb_shoulder_angles(isb_thorax_frame(ij, px, c7, t8), R_h,
                                                 params["shoulder_sequence"], params["gimbal_tol"])
            flag = flag & np.all(np.isfinite(shoulder), axis=-1)
        if forearm:
            R_f = isb_forearm_frame(_points(inputs, "US", n), _points(inputs, "RS", n), EL, EM, side=params["side"])
            elbow = isb_elbow_angles(R_h, R_f)
        context.progress(1, 1, "done")
        return {"shoulder": shoulder, "near_gimbal_lock": flag, "elbow": elbow}


ALGORITHMS = [Derivatives, Filter, RigidBodyMotionAlgorithm, AngularMomentum, RSSRAngles,
              UpperLimbAnglesAlgorithm, ISBAngles]
