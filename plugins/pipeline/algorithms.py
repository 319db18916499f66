"""Algorithm adapters of the demo pipeline glue.

Algorithms (each a thin wrapper of a pure function of this package):
``lab_survey`` (surveyed camera centre and mirror corners as arrays), ``match_grid``,
``split_views``, ``estimate_epipole``, ``assign_views``, ``mirror_tracks`` and ``rssr_markers``
(which track is which spherical joint, and the frame times).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext
from mirrorlab.plugins.photogrammetry.camera_arrays import CAMERA_KEYS
from scipy.stats import theilslopes

from .epipole import estimate_epipole
from .errors import SurveyError, ViewSplitError
from .grid import match_grid
from .tracks import assign_views, mirror_tracks
from .views import camera_projection, mirror_outline, split_views

if TYPE_CHECKING:
    pass

_CAMERA_PORTS = tuple(Port(k, f"camera array {k} (a /calibration/<camera> group)", optional=True)
                      for k in CAMERA_KEYS)


def _camera(inputs: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
    return {k: np.asarray(inputs[k]) for k in CAMERA_KEYS if k in inputs}


class LabSurvey(Algorithm):
    """Lab measurements taken by hand (thesis §3.6.1): camera centre F1 and the mirror's corners."""

    name = "lab_survey"
    version = "0.1.0"
    description = "surveyed camera centre and mirror corners (mm) as arrays for later steps"
    parameters = ParameterSet(
        Parameter("camera_center", float, unit="mm", shape=(3,), help="camera centre F1 x, y, z, measured in the lab"),
        Parameter("mirror_corners", float, unit="mm", shape=(None, 3),
                  help="mirror corners 'x, y, z; x, y, z; ...', in order around it (at least 3)"),
    )
    inputs = ()
    outputs = (Port("camera_center", "(3,) camera centre F1", "mm"),
               Port("mirror_corners", "(V, 3) mirror corners", "mm"),
               Port("mirror_point", "(3,) centroid of the corners, the point G on the mirror", "mm"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        corners = np.asarray(params["mirror_corners"], float).reshape(-1, 3)
        if len(corners) < 3:
            raise SurveyError(f"mirror_corners needs at least 3 corners (x, y, z; ...), got {len(corners)}")
        return {"camera_center": np.asarray(params["camera_center"], float), "mirror_corners": corners,
                "mirror_point": corners.mean(axis=0)}


class MatchGrid(Algorithm):
    """Grid points of the blobs detected on a calibration frame (see :func:`.grid.match_grid`)."""

    name = "match_grid"
    version = "0.1.0"
    description = "match detected calibration-grid blobs to the grid's points (plane X, Y in mm)"
    parameters = ParameterSet(
        Parameter("pitch", float, 60.0, unit="mm", bounds=(0.0, None), help="grid pitch"),
        Parameter("references", float, shape=(2, 4), help="two identified discs 'X, Y, u, v; X, Y, u, v': grid "
                                                           "point (X, Y) mm near pixel (u, v)"),
        Parameter("frame", int, 0, bounds=(0, None), help="which frame of the detections is the grid"),
        Parameter("tol", float, 0.25, bounds=(0.01, 0.5), help="largest blob distance from its lattice point, pitches"),
    )
    inputs = (Port("xy", "(F, K, 2) detections of the calibration frames, NaN-padded", "px"),)
    outputs = (Port("image_xy", "(N, 2) matched blobs", "px"), Port("plane_xy", "(N, 2) their grid points", "mm"),
               Port("lattice", "(N, 2) grid indices round((X, Y) / pitch)"),
               Port("homography", "(3, 3) grid plane -> image", "px/mm"),
               Port("residual", "(N,) distance from the homography", "px"),
               Port("count", "() matched points"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        xy = np.asarray(inputs["xy"], float)
        if xy.ndim == 2:
            xy = xy[None]
        if xy.ndim != 3 or params["frame"] >= len(xy):
            raise ViewSplitError(f"xy must be (F, K, 2) with frame {params['frame']} in it, got shape {xy.shape}")
        context.progress(0, 1, "matching grid")
        m = match_grid(xy[params["frame"]], params["pitch"], np.asarray(params["references"]),
                       tol=params["tol"])
        context.progress(1, 1, "matched")
        return {"image_xy": m.image_xy, "plane_xy": m.plane_xy, "lattice": m.lattice, "homography": m.homography,
                "residual": m.residual, "count": len(m.image_xy)}


class SplitViews(Algorithm):
    """Mirror-image candidates: detections inside the projected outline of a mirror."""

    name = "split_views"
    version = "0.1.0"
    description = "detections inside a mirror's projected outline (candidate mirror images), per frame"
    inputs = (Port("xy", "(F, K, 2) detections, NaN-padded", "px"),
              Port("mirror_corners", "(V, 3) or (E, V, 3) corners of each mirror", "mm"),
              *_CAMERA_PORTS)
    outputs = (Port("virtual", "(F, M, 2) candidate mirror images, NaN-padded", "px"),
               Port("virtual_mirror", "(F, M) mirror of each candidate, -1 padding"),
               Port("virtual_row", "(F, M) row of each candidate in xy, -1 padding"),
               Port("view", "(F, K) -1 outside all outlines, k inside mirror k's, -2 padding"),
               Port("outline", "(E, V, 2) image outline of each mirror", "px"),
               Port("projection", "(3, 4) camera projection matrix (w > 0 in front)", "px"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        P = camera_projection(_camera(inputs))
        corners = np.asarray(inputs["mirror_corners"], float)
        corners = corners[None] if corners.ndim == 2 else corners
        outline = np.array([mirror_outline(P, c) for c in corners])
        context.progress(0, 1, "splitting views")
        virtual, vm, rows, view = split_views(inputs["xy"], list(outline))
        context.progress(1, 1, "split")
        return {"virtual": virtual, "virtual_mirror": vm, "virtual_row": rows, "view": view, "outline": outline,
                "projection": P}


class EstimateEpipole(Algorithm):
    """The mirror epipole from unpaired detections (RANSAC over direct/mirror lines of all frames)."""

    name = "estimate_epipole"
    version = "0.1.0"
    description = "mirror epipole from unpaired direct and mirror-image detections (no geometry needed)"
    parameters = ParameterSet(
        Parameter("tol", float, 1.0, bounds=(0.0, None), help="inlier epipolar distance, px"),
        Parameter("samples", int, 2000, bounds=(10, 10_000_000), help="RANSAC proposals"),
        Parameter("seed", int, 0, bounds=(0, None), help="random seed of the proposals"),
    )
    inputs = (Port("real", "(F, N, 2) possible direct images (e.g. every detection)", "px"),
              Port("virtual", "(F, M, 2) possible mirror images (split_views' virtual)", "px"))
    outputs = (Port("epipoles", "(1, 3) homogeneous mirror epipole, sign as mirror_epipole", "px"),
               Port("inliers", "() supporting direct/mirror combinations"),
               Port("rms", "() RMS epipolar distance of the inliers", "px"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        context.progress(0, 1, "estimating epipole")
        est = estimate_epipole(inputs["real"], inputs["virtual"], tol=params["tol"], samples=params["samples"],
                               seed=params["seed"])
        context.progress(1, 1, "epipole")
        return {"epipoles": est.epipole[None], "inliers": est.inliers, "rms": est.rms}


class AssignViews(Algorithm):
    """Direct images and their mirror images from a pairing of every detection (see :func:`.tracks.assign_views`)."""

    name = "assign_views"
    version = "0.1.0"
    description = "direct images with their paired mirror images, from pair_mirror over all detections"
    inputs = (Port("xy", "(F, K, 2) detections (pair_mirror's real input)", "px"),
              Port("virtual_row", "(F, M) row of each candidate in xy (split_views)"),
              Port("virtual_index", "(F, K, E) pair_mirror output"),
              Port("paired_xy", "(F, K, E, 2) pair_mirror output virtual_xy", "px"))
    outputs = (Port("real", "(F, N, 2) direct images, NaN-padded", "px"),
               Port("paired", "(F, N, E, 2) mirror image of each direct image, NaN none", "px"),
               Port("real_row", "(F, N) row in xy, -1 padding"),
               Port("role", "(F, K) -1 direct, k mirror image in mirror k, -2 padding"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        real, paired, rows, role = assign_views(inputs["xy"], inputs["virtual_row"], inputs["virtual_index"],
                                                inputs["paired_xy"])
        context.progress(1, 1, "assigned")
        return {"real": real, "paired": paired, "real_row": rows, "role": role}


class MirrorTracks(Algorithm):
    """Each track's direct and mirror image per frame (see :func:`.tracks.mirror_tracks`)."""

    name = "mirror_tracks"
    version = "0.1.0"
    description = "carry real/mirror pairs along the tracks: (F, T, 2) real + virtual images"
    parameters = ParameterSet(Parameter("mirror", int, 0, bounds=(0, None), help="which mirror's images"))
    inputs = (Port("real", "(F, N, 2) direct images the tracks were computed on", "px"),
              Port("track_index", "(F, T) track output index", ""),
              Port("paired", "(F, N, E, 2) mirror image of each direct image", "px"))
    outputs = (Port("real_xy", "(F, T, 2) direct image of each track", "px"),
               Port("virtual_xy", "(F, T, 2) its mirror image", "px"),
               Port("pairs", "(T,) frames with both images per track"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        r, v = mirror_tracks(inputs["real"], inputs["track_index"], inputs["paired"], params["mirror"])
        both = np.all(np.isfinite(r), axis=2) & np.all(np.isfinite(v), axis=2)
        context.progress(1, 1, "tracks paired")
        return {"real_xy": r, "virtual_xy": v, "pairs": both.sum(axis=0)}


class RSSRMarkers(Algorithm):
    """Which reconstructed track is the input-crank joint S_A and which the output joint S_C; frame times.

    Frame times are ``(frame_index - first) x period``. The period is ``1 / frame_rate`` when given
    (a scanned film: the recorded stamps are when each frame was digitised, seconds apart and
    irregular, not when it was shot), else the Theil-Sen slope of the stamps against the index.
    """

    name = "rssr_markers"
    version = "0.1.0"
    description = "label RSSR tracks S_A / S_C by their distance from the input axis; frame times"
    parameters = ParameterSet(
        Parameter("O_A", float, (0.0, 0.0, 0.0), unit="mm", shape=(3,), help="input pivot x, y, z, world frame"),
        Parameter("e", float, (0.0, 0.0, 1.0), shape=(3,), help="input axis direction x, y, z"),
        Parameter("crank", float, 61.0, unit="mm", bounds=(0.0, None), help="input crank radius |a0|"),
        Parameter("frame_rate", float, 0.0, unit="Hz", bounds=(0.0, None),
                  help="shooting rate of the frames; 0 = estimate it from the recorded stamps. Give it for "
                       "a scanned film: its stamps are scan times, not the camera's"),
    )
    inputs = (Port("points", "(F, T, 3) reconstructed tracks", "mm"),
              Port("time", "(F,) recorded frame stamps", "s"),
              Port("frame_index", "(F,) frame numbers"))
    outputs = (Port("S_A", "(F, 3) input-crank joint", "mm"), Port("S_C", "(F, 3) output-crank joint", "mm"),
               Port("tracks", "(2,) track numbers of S_A and S_C"),
               Port("time", "(F,) frame time k x period from the first frame", "s"),
               Port("frame_period", "() frame period: 1 / frame_rate, else the Theil-Sen slope of the stamps", "s"))

    def run(self, inputs: Mapping[str, np.ndarray], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        pts = np.asarray(inputs["points"], float)
        stamp = np.asarray(inputs["time"], float).reshape(-1)
        index = np.asarray(inputs["frame_index"], float).reshape(-1)
        if pts.ndim != 3 or pts.shape[2] != 3 or pts.shape[1] < 2 or not (len(pts) == len(stamp) == len(index)):
            raise ViewSplitError(f"points must be (F, T >= 2, 3) with F = len(time) = len(frame_index); got "
                                 f"{pts.shape}, {stamp.shape}, {index.shape}")
        O, e = np.asarray(params["O_A"]), np.asarray(params["e"])
        e = e / np.linalg.norm(e)
        rel = pts - O
        radial = np.linalg.norm(rel - (rel @ e)[..., None] * e, axis=2)          # (F, T)
        seen = np.isfinite(radial).sum(axis=0)
        if not np.any(seen):
            raise ViewSplitError("no track was reconstructed in any frame; check the pairing and reconstruction")
        med = np.array([np.median(col[np.isfinite(col)]) if np.isfinite(col).any() else np.inf for col in radial.T])
        a = int(np.argmin(np.abs(med - params["crank"])))
        others = [t for t in np.argsort(-seen) if t != a]
        c = int(others[0])
        # the camera's frame period: Theil-Sen slope of stamp vs frame number (median of all pairwise
        # slopes: distant pairs average out the stamping jitter, and one late frame does not matter)
        if params["frame_rate"] > 0:     # a film's frame k was shot at k / rate, whenever it was scanned
            period = 1.0 / params["frame_rate"]
        else:
            period = float(theilslopes(stamp, index)[0]) if len(np.unique(index)) > 1 else float("nan")
        time = (index - index[0]) * period if len(index) > 1 else np.zeros(1)
        context.progress(1, 1, "labelled")
        return {"S_A": pts[:, a], "S_C": pts[:, c], "tracks": np.array([a, c]), "time": time,
                "frame_period": period}


ALGORITHMS = [LabSurvey, MatchGrid, SplitViews, EstimateEpipole, AssignViews, MirrorTracks, RSSRMarkers]
