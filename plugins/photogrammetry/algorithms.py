"""Algorithm adapters of the photogrammetry functions (``mirrorlab plugins`` lists them).

``calibrate_plane``, ``calibrate_pinhole``, ``mirror_normal``, ``reconstruct_parallel``,
``reconstruct_central``, ``reconstruct_mirror``, ``mirror_error_analysis``. Each is a thin wrapper:
the mathematics lives in :mod:`.cameras`, :mod:`.frames`, :mod:`.mirror` and :mod:`.sensitivity`.
Units: mm, px, rad. See ``docs/photogrammetry.md``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext

from .camera_arrays import CAMERA_KEYS, camera_from_arrays, pinhole_arrays, plane_arrays
from .cameras import calibrate_pinhole, fit_plane_calibration
from .central import CentralCamera
from .errors import InvalidArgument, PhotogrammetryError
from .frames import (
    _renumber,
    image_to_film,
    mirror_normal_frames,
    reconstruct_central_frames,
    reconstruct_mirror_frames,
    reconstruct_parallel_frames,
)
from .sensitivity import (
    MirrorScene,
    mirror_angle_sweep,
    mirror_point_sensitivity,
    mirror_reconstruct,
    monte_carlo,
    sphere_points,
)

if TYPE_CHECKING:
    pass

_CAMERA_PORTS = (
    Port("plane_coefficients", "plane calibration: (6, 2) quadratic or (8 + k,) projective coefficients", "",
         optional=True),
    Port("plane_center", "plane calibration: (2,) image normalisation centre", "px", optional=True),
    Port("plane_scale", "plane calibration: () image normalisation scale", "px", optional=True),
    Port("plane_z", "plane calibration: () Z of the calibration plane", "mm", optional=True),
    Port("camera_center", "plane calibration: (3,) camera centre F1", "mm", optional=True),
    Port("camera_matrix", "pinhole: (3, 3) intrinsic matrix K", "px", optional=True),
    Port("dist_coeffs", "pinhole: (k,) OpenCV distortion coefficients", "", optional=True),
    Port("rotation", "pinhole: (3, 3) world -> camera rotation", "", optional=True),
    Port("translation", "pinhole: (3,) world -> camera translation", "mm", optional=True),
)


def _camera(inputs: Mapping[str, np.ndarray]) -> Any:
    return camera_from_arrays({k: inputs[k] for k in CAMERA_KEYS if k in inputs})


def _optional(inputs: Mapping[str, np.ndarray], name: str) -> np.ndarray | None:
    value = inputs.get(name)
    return None if value is None else np.asarray(value)


# ------------------------------------------------------------------------------------------------ calibration


class CalibratePlane(Algorithm):
    """Thesis image -> calibration-plane map (eqs 3.15–3.20) or a homography with radial terms."""

    name = "calibrate_plane"
    version = "1.0.0"
    description = "plane calibration: quadratic image -> plane map (thesis 3.15-3.20) or projective (homography)"
    parameters = ParameterSet(
        Parameter("model", str, "quadratic", choices=("quadratic", "projective"),
                  help="quadratic: thesis (exact only with the film parallel to the plane); projective: any tilt"),
        Parameter("plane_z", float, 0.0, unit="mm", help="Z of the calibration plane"),
        Parameter("radial_terms", int, 0, bounds=(0, 6), help="radial distortion terms of the projective model"),
        Parameter("solver", str, "lstsq", choices=("lstsq", "normal_equations"),
                  help="quadratic: QR least squares, or the thesis normal equations (3.19)"),
        Parameter("max_condition", float, 1e10, bounds=(1.0, None), help="largest accepted condition number"),
    )
    inputs = (Port("image_xy", "(N, 2) image coordinates of the calibration points", "px"),
              Port("plane_xy", "(N, 2) their X, Y on the calibration plane", "mm"),
              Port("camera_center", "(3,) camera centre F1 (object-space principal point)", "mm"))
    outputs = (Port("plane_coefficients", "(6, 2) quadratic or (8 + k,) projective coefficients (normalised image)"),
               Port("plane_center", "(2,) image normalisation centre", "px"),
               Port("plane_scale", "() image normalisation scale", "px"),
               Port("plane_z", "() Z of the calibration plane", "mm"),
               Port("camera_center", "(3,) camera centre F1", "mm"),
               Port("residuals", "(N, 2) mapped minus true plane coordinates", "mm"),
               Port("rms", "() RMS residual", "mm"), Port("max_residual", "() largest residual", "mm"),
               Port("condition", "() condition number of the fit"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        context.progress(0, 1, "fitting")
        cal = fit_plane_calibration(inputs["image_xy"], inputs["plane_xy"], params["plane_z"], inputs["camera_center"],
                                    model=params["model"], solver=params["solver"],
                                    radial_terms=params["radial_terms"], max_condition=params["max_condition"])
        context.progress(1, 1, "done")
        return {**plane_arrays(cal), "residuals": cal.residuals, "rms": cal.rms, "max_residual": cal.max_residual,
                "condition": cal.condition}


class CalibratePinhole(Algorithm):
    """Zhang calibration (cv2.calibrateCamera) from views of a planar target."""

    name = "calibrate_pinhole"
    version = "1.0.0"
    description = "pinhole + distortion camera from views of a planar grid (OpenCV, Zhang)"
    parameters = ParameterSet(
        Parameter("fix_aspect_ratio", bool, False, help="constrain fx = fy (CALIB_FIX_ASPECT_RATIO)"),
        Parameter("reference_view", int, 0, bounds=(0, None), help="view whose board frame becomes the world frame"),
    )
    inputs = (Port("object_points", "(views, M, 3) target points (Z = 0 for a board)", "mm"),
              Port("image_points", "(views, M, 2) detected image points; NaN rows are skipped", "px"),
              Port("image_size", "(2,) width, height", "px"))
    outputs = (Port("camera_matrix", "(3, 3) intrinsic matrix K", "px"),
               Port("dist_coeffs", "(k,) distortion k1, k2, p1, p2, k3", ""),
               Port("rotation", "(3, 3) world -> camera rotation of the reference view"),
               Port("translation", "(3,) world -> camera translation of the reference view", "mm"),
               Port("camera_center", "(3,) camera centre in the reference board frame", "mm"),
               Port("rms", "() RMS reprojection error", "px"),
               Port("per_view_rms", "(views,) RMS reprojection error per view", "px"),
               Port("view_rotations", "(views, 3, 3) rotation of every view"),
               Port("view_translations", "(views, 3) translation of every view", "mm"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        obj = np.asarray(inputs["object_points"], float)
        img = np.asarray(inputs["image_points"], float)
        if obj.ndim != 3 or img.ndim != 3 or obj.shape[:2] != img.shape[:2] or obj.shape[2] != 3 or img.shape[2] != 2:
            raise InvalidArgument(f"object_points must be (views, M, 3) and image_points (views, M, 2) with the same "
                                  f"views and M; got {obj.shape} and {img.shape}")
        keep = np.isfinite(img).all(-1) & np.isfinite(obj).all(-1)
        size = np.asarray(inputs["image_size"]).astype(int).ravel()
        if params["reference_view"] >= obj.shape[0]:
            raise InvalidArgument(f"reference_view {params['reference_view']} does not exist ({obj.shape[0]} views)")
        context.progress(0, 1, f"calibrating from {obj.shape[0]} views")
        cam = calibrate_pinhole([o[k] for o, k in zip(obj, keep)], [i[k] for i, k in zip(img, keep)],
                                (int(size[0]), int(size[1])), fix_aspect_ratio=params["fix_aspect_ratio"],
                                reference_view=params["reference_view"])
        context.progress(1, 1, "done")
        return {**pinhole_arrays(cam), "rms": cam.rms, "per_view_rms": cam.per_view_rms,
                "view_rotations": np.stack([R for R, _ in cam.views]),
                "view_translations": np.stack([t for _, t in cam.views])}


# ------------------------------------------------------------------------------------------------ mirror


class MirrorNormalAlgorithm(Algorithm):
    """Mirror normal from markers seen directly and in the mirror (eqs 3.8–3.10)."""

    name = "mirror_normal"
    version = "1.0.0"
    description = "mirror normal (and virtual camera) from marker / mirror-image pairs (thesis 3.8-3.12)"
    parameters = ParameterSet(
        Parameter("method", str, "lstsq", choices=("lstsq", "thesis"),
                  help="least squares over all pairs, or the Appendix 2 average of pair groups"),
        Parameter("per_frame", bool, False, help="one normal per frame (mirror moving)"),
    )
    inputs = (Port("real_xy", "(frames, markers, 2) direct images, NaN if not seen", "px"),
              Port("virtual_xy", "(frames, markers, 2) mirror images, NaN if not seen", "px"),
              Port("mirror_point", "(3,) point G on the mirror (orients the normal, gives F2)", "mm", optional=True),
              *_CAMERA_PORTS)
    outputs = (Port("normal", "(3,) or (frames, 3) unit normal toward the camera"),
               Port("residual", "() or (frames,) RMS misfit of the pair planes (≈ rad)", "rad"),
               Port("pairs", "() or (frames,) pairs used"),
               Port("virtual_center", "(3,) or (frames, 3) virtual camera F2 (NaN without mirror_point)", "mm"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        cam = _camera(inputs)
        G = _optional(inputs, "mirror_point")
        context.progress(0, 1, "estimating")
        n, resid, pairs = mirror_normal_frames(cam, inputs["real_xy"], inputs["virtual_xy"], G, params["method"],
                                               params["per_frame"])
        if G is None:
            F2 = np.full(n.shape, np.nan)
        else:
            F1 = np.asarray(cam.camera_center, float)
            F2 = F1 - 2.0 * (((F1 - G.reshape(3)) * n).sum(-1))[..., None] * n  # (3.11)
        context.progress(1, 1, "done")
        return {"normal": n, "residual": resid, "pairs": pairs, "virtual_center": F2}


#: Markers per block of the frame-chunked reconstruction (progress, cancellation, bounded memory).
_BLOCK = 250_000


class ReconstructMirror(Algorithm):
    """One camera + one plane mirror: markers from their direct and mirror images (thesis §3.2)."""

    name = "reconstruct_mirror"
    version = "1.0.0"
    description = "mirror method: 3-D markers from direct and mirror images with one camera (thesis 3.1-3.13)"
    parameters = ParameterSet(
        Parameter("triangulation", str, "midpoint", choices=("midpoint", "optimal"),
                  help="thesis midpoint (3.5-3.7), or minimum reprojection error"),
        Parameter("max_gap", float, 0.0, unit="mm", bounds=(0.0, None),
                  help="reject markers whose rays miss each other by more (0: no limit)"),
        Parameter("on_degenerate", str, "raise", choices=("raise", "nan"),
                  help="degenerate markers fail the run naming frame and marker, or become NaN"),
        Parameter("normal_method", str, "lstsq", choices=("lstsq", "thesis"),
                  help="normal from the data when no normal is given: least squares or the thesis average"),
        Parameter("per_frame_normal", bool, False, help="estimate the normal per frame (moving mirror)"),
    )
    inputs = (Port("real_xy", "(frames, markers, 2) direct images, NaN if not seen", "px"),
              Port("virtual_xy", "(frames, markers, 2) mirror images, NaN if not seen", "px"),
              Port("mirror_point", "(3,) point G on the mirror", "mm"),
              Port("normal", "(3,) or (frames, 3) mirror normal toward the camera; estimated from the data if absent",
                   optional=True),
              *_CAMERA_PORTS)
    outputs = (Port("points", "(frames, markers, 3) marker positions, NaN where not reconstructed", "mm"),
               Port("gap", "(frames, markers) miss distance of the real and mirror rays", "mm"),
               Port("angle", "(frames, markers) intersection angle of the rays", "rad"),
               Port("normal", "(3,) or (frames, 3) mirror normal used"),
               Port("virtual_center", "(3,) or (frames, 3) virtual camera F2", "mm"),
               Port("reprojection", "(frames, markers) RMS reprojection error (optimal only, else NaN)", "px"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        cam = _camera(inputs)
        real = np.asarray(inputs["real_xy"], float)
        virt = np.asarray(inputs["virtual_xy"], float)
        if real.ndim == 2:
            real, virt = real[None], virt[None]
        G = np.asarray(inputs["mirror_point"], float)
        normal = _optional(inputs, "normal")
        if normal is None:
            context.progress(0, None, "mirror normal from the data")
            normal = mirror_normal_frames(cam, real, virt, G, params["normal_method"], params["per_frame_normal"])[0]
        n_frames = real.shape[0]
        step = max(1, _BLOCK // max(1, real.shape[1]))
        parts = []
        for lo in range(0, n_frames, step):  # blocks of frames, each vectorised
            context.progress(lo, n_frames, "triangulating")
            hi = min(lo + step, n_frames)
            n_block = normal[lo:hi] if normal.ndim == 2 else normal
            try:
                parts.append(reconstruct_mirror_frames(
                    cam, real[lo:hi], virt[lo:hi], G, n_block, params["triangulation"],
                    params["max_gap"] or None, params["on_degenerate"]))
            except PhotogrammetryError as exc:
                raise _renumber(exc, np.arange(lo, hi)) from exc
        context.progress(n_frames, n_frames, "done")
        def cat(key: str) -> np.ndarray:
            return np.concatenate([getattr(p, key) for p in parts])

        per_frame = normal.ndim == 2
        return {"points": cat("points"), "gap": cat("gap"), "angle": cat("angle"),
                "normal": cat("normal") if per_frame else parts[0].normal,
                "virtual_center": cat("virtual_center") if per_frame else parts[0].virtual_center,
                "reprojection": cat("reprojection")}


# ------------------------------------------------------------------------------------------------ chains


class ReconstructParallel(Algorithm):
    """Chains of markers with known link lengths under parallel projection (thesis §2.2)."""

    name = "reconstruct_parallel"
    version = "1.0.0"
    description = "parallel projection: marker chain with known link lengths from one view (thesis 2.7-2.11)"
    parameters = ParameterSet(
        Parameter("magnification", float, 1.0, bounds=(1e-12, None),
                  help="object mm per image unit (L / ell, times the pixel size for pixel input)"),
        Parameter("tol_radicand", float, 1e-3, bounds=(0.0, 1.0),
                  help="clamp negative radicands down to -tol * D^2 (flag segment_in_image_plane)"),
    )
    inputs = (Port("image_xy", "(frames, N, 2) image coordinates of markers 0..N-1 (0 = reference), NaN if not seen"),
              Port("lengths", "(N-1,) or (frames, N-1) link lengths, link n joins markers n-1 and n", "mm"),
              Port("signs", "(N-1,) or (frames, N-1) +1 if marker n is further from the camera than n-1, else -1"))
    outputs = (Port("points", "(frames, N, 3) markers in the frame of marker 0 (Z along the view)", "mm"),
               Port("segment_in_image_plane", "(frames, N) radicand clamped to 0"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        context.progress(0, 1, "reconstructing")
        pts, flag = reconstruct_parallel_frames(inputs["image_xy"], inputs["lengths"], params["magnification"],
                                                inputs["signs"], params["tol_radicand"])
        context.progress(1, 1, "done")
        return {"points": pts, "segment_in_image_plane": flag}


class ReconstructCentral(Algorithm):
    """Chains of markers with known link lengths from one tilted central projection (thesis §2.3)."""

    name = "reconstruct_central"
    version = "1.0.0"
    description = "central projection: marker chain with known link lengths from one tilted camera (thesis 2.12-2.28)"
    parameters = ParameterSet(
        Parameter("a", float, None, unit="mm", bounds=(0.0, None), help="distance film -> reference point K"),
        Parameter("f", float, None, unit="mm", bounds=(0.0, None), help="focal length"),
        Parameter("alpha", float, 0.0, unit="rad", bounds=(-1.5, 1.5), help="tilt of the optical axis, + looking down"),
        Parameter("pixel_size", float, 1.0, unit="mm", bounds=(0.0, None),
                  help="film mm per image unit (1 when image_xy is already film mm)"),
        Parameter("y_down", bool, False, help="image y points down (pixel rows); the film y of the thesis points up"),
        Parameter("tol_z", float, 0.5, unit="mm", bounds=(0.0, None), help="roots closer than this coincide"),
        Parameter("beta_max", float, float(np.radians(2.0)), unit="rad", bounds=(0.0, 1.0),
                  help="auxiliary-marker test: largest accepted misalignment"),
        Parameter("beta_sep", float, float(np.radians(1.0)), unit="rad", bounds=(0.0, 1.0),
                  help="auxiliary-marker test: required separation of the two roots"),
    )
    inputs = (Port("image_xy", "(frames, N, 2) images of markers 1..N in chain order (K is marker 0), NaN if not seen"),
              Port("lengths", "(N,) or (frames, N) link lengths, the first from K", "mm"),
              Port("signs", "(N,) or (frames, N) root per link: +1 far, -1 near, 0 undecided", optional=True),
              Port("aux_xy", "(frames, N, 2) auxiliary marker on each link, NaN if none", optional=True),
              Port("aux_lengths", "(N,) distance of each auxiliary marker from the previous marker", "mm",
                   optional=True),
              Port("principal_point", "(2,) image of the optical axis, in image units", optional=True),
              Port("start", "(3,) chain start instead of K", "mm", optional=True))
    outputs = (Port("points", "(frames, N, 3) markers 1..N (world frame of thesis §2.3)", "mm"),
               Port("signs", "(frames, N) root used (0: coincident roots, or not reconstructed)"),
               Port("tangent_ray", "(frames, N) ray (nearly) tangent to the link sphere"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        cam = CentralCamera(params["a"], params["f"], params["alpha"])
        pp = _optional(inputs, "principal_point")

        def film(xy: np.ndarray | None) -> np.ndarray | None:
            return None if xy is None else image_to_film(xy, params["pixel_size"], pp, params["y_down"])

        context.progress(0, 1, "reconstructing")
        pts, signs, tangent = reconstruct_central_frames(
            film(inputs["image_xy"]), inputs["lengths"], cam, _optional(inputs, "signs"),
            film(_optional(inputs, "aux_xy")), _optional(inputs, "aux_lengths"), _optional(inputs, "start"),
            tol_z=params["tol_z"], beta_max=params["beta_max"], beta_sep=params["beta_sep"])
        context.progress(1, 1, "done")
        return {"points": pts, "signs": signs, "tangent_ray": tangent}


# ------------------------------------------------------------------------------------------------ error analysis

_ERROR_NAMES = ("Ux", "Uy", "Vx", "Vy", "Fx", "Fy", "Fz", "Gx", "Gz", "T")


class MirrorErrorAnalysis(Algorithm):
    """Sensitivity (Table 3.1), error map (Fig. 3.22), Monte Carlo and mirror-angle sweep (Fig. 3.23)."""

    name = "mirror_error_analysis"
    version = "1.0.0"
    description = "mirror-method error analysis on the thesis geometry: sensitivities, Monte Carlo, angle sweep"
    parameters = ParameterSet(
        Parameter("mirror_angle", float, float(np.radians(50.0)), unit="rad", bounds=(0.05, 1.55),
                  help="vertical mirror turned about Y: normal (cos T, 0, sin T)"),
        Parameter("focal", float, 30.0, unit="mm", bounds=(1.0, None), help="lens focal length (film parallel to Z=0)"),
        Parameter("radius", float, 100.0, unit="mm", bounds=(0.0, None),
                  help="sphere of markers about (100, 50, 300) mm when no points are given"),
        Parameter("n_lat", int, 9, bounds=(3, 90), help="latitude rings of the sphere (incl. poles)"),
        Parameter("n_lon", int, 16, bounds=(1, 360), help="points per ring"),
        Parameter("err_film", float, 0.003, unit="mm", bounds=(0.0, None), help="film reading error (Ux Uy Vx Vy)"),
        Parameter("err_camera", float, 1.0, unit="mm", bounds=(0.0, None), help="error of the camera centre (Fx Fy Fz)"),
        Parameter("err_mirror_point", float, 1.0, unit="mm", bounds=(0.0, None), help="error of G (Gx Gz)"),
        Parameter("err_normal", float, 1e-4, unit="rad", bounds=(0.0, None), help="error of the mirror angle (T)"),
        Parameter("mc_samples", int, 200, bounds=(0, 100000), help="Monte Carlo samples (0: skip)"),
        Parameter("seed", int, 0, bounds=(0, None), help="Monte Carlo random seed"),
        Parameter("sweep_min", float, 0.2, unit="rad", bounds=(0.05, 1.55), help="mirror-angle sweep start"),
        Parameter("sweep_max", float, 1.4, unit="rad", bounds=(0.05, 1.55), help="mirror-angle sweep end"),
        Parameter("sweep_steps", int, 25, bounds=(0, 1000), help="mirror-angle sweep samples (0: skip)"),
    )
    inputs = (Port("points", "(M, 3) markers to analyse (default: the sphere)", "mm", optional=True),)
    outputs = (Port("points", "(M, 3) analysed markers", "mm"),
               Port("parameter_names", "(10,) Ux Uy Vx Vy Fx Fy Fz Gx Gz T (order of contributions)"),
               Port("contributions", "(10, M, 3) dR/da_n * da_n per parameter (eq. 2.30)", "mm"),
               Port("table", "(10,) mean |contribution| per parameter over the markers (Table 3.1 column b)", "mm"),
               Port("signed_sum", "(M, 3) sum of contributions (eq. 2.30)", "mm"),
               Port("abs_sum", "(M, 3) sum of |contributions| (worst case)", "mm"),
               Port("rss", "(M, 3) root-sum-square of contributions", "mm"),
               Port("mc_std", "(M, 3) Monte Carlo standard deviation (NaN if skipped)", "mm"),
               Port("mc_bias", "(M, 3) Monte Carlo mean minus nominal (NaN if skipped)", "mm"),
               Port("sweep_angles", "(A,) mirror angles of the sweep", "rad"),
               Port("sweep_error", "(A,) mean total error |c| summed over parameters", "mm"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        scene = MirrorScene.thesis(params["mirror_angle"], params["focal"])
        pts = _optional(inputs, "points")
        pts = sphere_points((100.0, 50.0, 300.0), params["radius"], params["n_lat"], params["n_lon"]) \
            if pts is None else np.atleast_2d(np.asarray(pts, float))
        e = params
        errors = {"Ux": e["err_film"], "Uy": e["err_film"], "Vx": e["err_film"], "Vy": e["err_film"],
                  "Fx": e["err_camera"], "Fy": e["err_camera"], "Fz": e["err_camera"],
                  "Gx": e["err_mirror_point"], "Gz": e["err_mirror_point"], "T": e["err_normal"]}
        if min(errors.values()) <= 0:
            raise InvalidArgument("every error (err_film, err_camera, err_mirror_point, err_normal) must be > 0 "
                                  "for the central differences of eq. 2.31")
        steps = params["sweep_steps"]
        total = 2 + (params["mc_samples"] > 0) + steps
        context.progress(0, total, "sensitivities")
        sens = mirror_point_sensitivity(scene, pts, errors)
        mag = np.linalg.norm(sens.contributions, axis=-1)  # (10, M)
        mc_std = mc_bias = np.full(pts.shape, np.nan)
        done = 1
        if params["mc_samples"] > 0:
            context.progress(done, total, "Monte Carlo")
            U, V = scene.image_points(pts)
            mc = monte_carlo(lambda p: mirror_reconstruct(scene, U, V, p), {k: 0.0 for k in errors}, errors,
                             n=params["mc_samples"], rng=params["seed"])
            mc_std, mc_bias = mc.std, mc.bias
            done += 1
        angles = np.linspace(params["sweep_min"], params["sweep_max"], steps)
        sweep = np.empty(steps)
        for i, T in enumerate(angles):  # one vectorised sensitivity per angle
            context.progress(done + i, total, "mirror-angle sweep")
            sweep[i] = mirror_angle_sweep(scene, pts, [T], errors)[0]
        context.progress(total, total, "done")
        return {"points": pts, "parameter_names": np.array(_ERROR_NAMES, dtype="S"),
                "contributions": sens.contributions, "table": mag.mean(axis=1), "signed_sum": sens.signed_sum,
                "abs_sum": sens.abs_sum, "rss": sens.rss, "mc_std": mc_std, "mc_bias": mc_bias,
                "sweep_angles": angles, "sweep_error": sweep}


ALGORITHMS = [CalibratePlane, CalibratePinhole, MirrorNormalAlgorithm, ReconstructParallel, ReconstructCentral,
              ReconstructMirror, MirrorErrorAnalysis]
