"""Framework adapters of the mechanism functions: each algorithm reads arrays, calls one function.

=====================  ==========================================  ====================================
algorithm              inputs                                      outputs
=====================  ==========================================  ====================================
``rigid_groups``       tracks (T, M, 2|3)                          group (M,), stationary (M,), tol, std
``four_bar``           points (T, M, 2) unlabeled, NaN-padded      lengths (4,), ground_pivots, joints,
                                                                   residuals, rms, tracks, link (M,), scale
``swept_area``         a, b (T, 2) or (T, 3) rod ends              area, crossings
``centrodes``          a, b (T, 2) rod ends                        fixed, moving
``arc_wall_grid``      (none)                                      c, h, area, best
``optimal_wall``       (none)                                      w, nodes, area, area_positions,
                                                                   area_thesis, area_grid, start_area, ...
``spherical_joint``    body1, body2 (T, m, 3)                      centre, local1, local2, residual, rms
``revolute_joint``     body1, body2 (T, m, 3)                      point, direction, angle, residual, rms
=====================  ==========================================  ====================================

Units: mm, mm², rad (the wall problem: the units of its rod length ``l``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
from mirrorlab.core import Algorithm, Parameter, ParameterSet, Port, RunContext

from .errors import GroupingError, InvalidPoints
from .fourbar import LINK_NAMES, reconstruct_four_bar
from .grouping import rigid_groups
from .joints import revolute_joint, spherical_joint
from .swept import segment_swept_area, spatial_swept_area
from .walls import ARC_C, ARC_H, THESIS_WALL_NODES, arc_grid, centrodes, optimal_wall

__all__ = ["ALGORITHMS", "ArcWallGrid", "Centrodes", "FourBarAlgorithm", "OptimalWallAlgorithm", "RevoluteJointAlgorithm",
           "RigidGroupsAlgorithm", "SphericalJointAlgorithm", "SweptArea"]


def _array(inputs: Mapping[str, Any], name: str) -> np.ndarray:
    return np.asarray(inputs[name], dtype=float)


class RigidGroupsAlgorithm(Algorithm):
    """Rigid bodies among tracked markers (maximal cliques of constant distances)."""

    name = "rigid_groups"
    version = "0.1.0"
    description = "which tracked markers share a rigid body (constant distances); the stationary body is ground"
    parameters = ParameterSet(
        Parameter("tol", float, 0.0, unit="mm", bounds=(0.0, None),
                  help="largest std of a rigid distance (0: estimated from the noise)"),
        Parameter("smoothness", float, 2.0, bounds=(0.0, None),
                  help="a rigid distance varies like noise: std <= smoothness x frame-to-frame noise (0: off)"),
    )
    inputs = (Port("tracks", "(T, M, 2|3) tracked markers, NaN where missing", "mm"),)
    outputs = (Port("group", "(M,) body of each marker (0 = ground when there is one), -1 none; a marker in "
                             "several bodies gets the first"),
               Port("stationary", "(M,) 1 for markers that do not move"),
               Port("tol", "() tolerance used", "mm"),
               Port("std", "(M, M) std of each inter-marker distance", "mm"))

    def run(self, inputs: Mapping[str, Any], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        g = rigid_groups(_array(inputs, "tracks"), tol=params["tol"] or None, smoothness=params["smoothness"] or None)
        group = np.full(g.std.shape[0], -1)
        for k in reversed(range(len(g.groups))):
            group[list(g.groups[k])] = k
        return {"group": group, "stationary": g.stationary.astype(np.int8), "tol": g.tol, "std": g.std}


class FourBarAlgorithm(Algorithm):
    """Planar four-bar from unlabeled marker positions (least squares, or the thesis's Steps 1-5)."""

    name = "four_bar"
    version = "0.1.0"
    description = "planar four-bar link lengths, pivots and joints from unlabeled markers (analysis.md §4)"
    parameters = ParameterSet(
        Parameter("method", str, "least_squares", choices=("least_squares", "thesis"),
                  help="least_squares: all frames + model fit; thesis: poles and inversion (Steps 1-5)"),
        Parameter("scale", float, 1.0, bounds=(0.0, None), help="mm per input unit (e.g. mm/px of the film scan)"),
        Parameter("reference_distance", float, 0.0, unit="mm", bounds=(0.0, None),
                  help="known distance of the two farthest-apart frame markers; sets the scale (thesis: P1P2)"),
        Parameter("tol", float, 0.0, unit="mm", bounds=(0.0, None),
                  help="rigidity tolerance (0: estimated from the noise)"),
        Parameter("tracking", str, "predictive", choices=("predictive", "nearest"), help="marker tracking rule"),
        Parameter("refine", bool, True, help="least squares: fit the four-bar model to every marker"),
        Parameter("min_travel", float, 32.0, bounds=(0.0, None),
                  help="thesis: path (input units) between the frames of successive poles (listing: 16 units)"),
        Parameter("inversion_step", int, 10, bounds=(1, None), help="thesis: circumcentres of frames N, N+step, N+2 step"),
        Parameter("inversion_starts", int, 10, bounds=(1, None), help="thesis: N = 0 .. starts-1"),
    )
    inputs = (Port("points", "(T, M, 2) marker positions per frame in any order, NaN-padded (e.g. detections)"),)
    outputs = (Port("lengths", "(4,) ground, input, coupler, output link lengths", "mm"),
               Port("ground_pivots", "(2, 2) G1 (input), G2 (output)", "mm"),
               Port("joints", "(T, 4, 2) G1, J1, J2, G2 per frame", "mm"),
               Port("residuals", "(T, M) distance of each moving marker from the fitted linkage", "mm"),
               Port("rms", "() RMS residual", "mm"),
               Port("tracks", "(T, M, 2) tracked (and registered) markers", "mm"),
               Port("link", "(M,) link of each track: 0 ground, 1 input, 2 coupler, 3 output, -1 none"),
               Port("scale", "() mm per input unit used"))

    def run(self, inputs: Mapping[str, Any], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        context.progress(0, 2, f"reconstructing ({params['method']})")
        fb = reconstruct_four_bar(_array(inputs, "points"), params["method"], tol=params["tol"] or None,
                                  tracking=params["tracking"], refine=params["refine"], min_travel=params["min_travel"],
                                  inversion_step=params["inversion_step"], inversion_starts=params["inversion_starts"])
        scale = float(params["scale"])
        if params["reference_distance"]:
            ground = fb.tracks[:, list(fb.links["ground"])]
            d = np.linalg.norm(ground[:, :, None] - ground[:, None], axis=-1)
            span = float(np.nanmax(np.nanmean(d, axis=0))) if len(fb.links["ground"]) >= 2 else 0.0
            if not span > 0:
                raise GroupingError("reference_distance needs two frame markers; the ground has "
                                    f"{len(fb.links['ground'])}")
            scale = params["reference_distance"] / span
        link = np.full(fb.tracks.shape[1], -1)
        for k, key in enumerate(("ground", "input", "coupler", "output")):
            link[list(fb.links[key])] = k
        context.progress(2, 2, "done")
        return {"lengths": np.array([fb.lengths[k] for k in LINK_NAMES]) * scale,
                "ground_pivots": fb.ground_pivots * scale, "joints": fb.joints * scale,
                "residuals": fb.residuals * scale, "rms": fb.rms * scale, "tracks": fb.tracks * scale,
                "link": link, "scale": scale}


class SweptArea(Algorithm):
    """Area swept by a rod: planar exact / thesis raster, spatial triangles / bilinear / union."""

    name = "swept_area"
    version = "0.1.0"
    description = "area swept by a moving rod from its end positions (analysis.md §5, §7)"
    parameters = ParameterSet(
        Parameter("method", str, "exact", choices=("exact", "raster", "triangles", "bilinear", "union"),
                  help="planar (T, 2): exact (polygon union) or raster (thesis 256 x 256 DDA); spatial (T, 3): "
                       "triangles (thesis), bilinear or union (a motion in one plane)"),
        Parameter("resolution", int, 256, bounds=(8, 100_000), help="raster: pixels across the motion"),
    )
    inputs = (Port("a", "(T, 2) or (T, 3) positions of end A", "mm"), Port("b", "(T, 2) or (T, 3) of end B", "mm"))
    outputs = (Port("area", "() swept area", "mm²"),
               Port("crossings", "(C,) steps i where rods i and i+1 cross (spatial methods)"))

    def run(self, inputs: Mapping[str, Any], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        a, b = _array(inputs, "a"), _array(inputs, "b")
        method = params["method"]
        planar = method in ("exact", "raster")
        if a.ndim != 2 or a.shape[1] != (2 if planar else 3):
            raise InvalidPoints(f"method {method!r} takes {'(T, 2)' if planar else '(T, 3)'} rod ends; a has shape "
                                f"{a.shape}: use {'triangles/bilinear/union' if planar else 'exact/raster'}")
        if planar:
            return {"area": segment_swept_area(a, b, method, resolution=params["resolution"]),
                    "crossings": np.zeros(0, np.int64)}
        s = spatial_swept_area(a, b, method)
        return {"area": s.area, "crossings": s.crossings}


class Centrodes(Algorithm):
    """Fixed and moving centrodes of a planar rod motion."""

    name = "centrodes"
    version = "0.1.0"
    description = "instantaneous centres of a planar rod motion: fixed (world) and moving (rod frame) centrodes"
    parameters = ParameterSet()
    inputs = (Port("a", "(T, 2) positions of end A", "mm"), Port("b", "(T, 2) positions of end B", "mm"))
    outputs = (Port("fixed", "(T, 2) fixed centrode (world), NaN for translations", "mm"),
               Port("moving", "(T, 2) moving centrode (rod frame: origin B, x along BA)", "mm"))

    def run(self, inputs: Mapping[str, Any], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        fixed, moving = centrodes(_array(inputs, "a"), _array(inputs, "b"))
        return {"fixed": fixed, "moving": moving}


class ArcWallGrid(Algorithm):
    """The circular-arc wall grid search of Fig. 6.11."""

    name = "arc_wall_grid"
    version = "0.1.0"
    description = "swept area of the arc-wall family on the thesis's grid of centres (Fig. 6.11)"
    parameters = ParameterSet(
        Parameter("l", float, 3.0, bounds=(0.0, None), help="rod length"),
        Parameter("positions", int, 4000, bounds=(10, 100_000), help="rod positions per motion"),
        Parameter("strips", int, 3000, bounds=(10, 100_000), help="strips of the area quadrature"),
    )
    inputs = ()
    outputs = (Port("c", "(nc,) centre abscissae, in units of the rod length l"),
               Port("h", "(nh,) centre heights, in units of l"),
               Port("area", "(nh, nc) swept areas, in units of l²"),
               Port("best", "(3,) c, h (units of l), area (units of l²) of the minimum"))

    def run(self, inputs: Mapping[str, Any], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        context.progress(0, 1, "arc grid")
        g = arc_grid(ARC_C, ARC_H, params["l"], params["positions"], params["strips"],
                     progress=lambda done, total: context.progress(done, total, "arc grid"))
        context.progress(1, 1, "done")
        return {"c": g.c, "h": g.h, "area": g.area, "best": np.array(g.best)}


class OptimalWallAlgorithm(Algorithm):
    """The 59-variable optimal wall of §6.2.1 d."""

    name = "optimal_wall"
    version = "0.1.0"
    description = "wall minimising the swept area (59 abscissae; L-BFGS-B or the thesis's Fletcher-Reeves CG)"
    parameters = ParameterSet(
        Parameter("method", str, "lbfgsb", choices=("lbfgsb", "fletcher_reeves"), help="solver"),
        Parameter("objective", str, "exact", choices=("exact", "positions"),
                  help="exact quadrature (with A's path crossing) or positions only (as the thesis)"),
        Parameter("l", float, 3.0, bounds=(0.0, None), help="rod length"),
        Parameter("positions", int, 400, bounds=(10, 100_000), help="rod positions of the objective"),
        Parameter("strips", int, 1000, bounds=(10, 100_000), help="strips of the objective"),
        Parameter("final_positions", int, 6000, bounds=(10, 100_000), help="positions of the final evaluation"),
        Parameter("final_strips", int, 5000, bounds=(10, 100_000), help="strips of the final evaluation"),
        Parameter("thesis_positions", int, 361, bounds=(10, 100_000),
                  help="positions of the thesis-like (positions-only) evaluation"),
        Parameter("maxiter", int, 400, bounds=(1, 100_000), help="solver iterations"),
    )
    inputs = ()
    outputs = (Port("w", "(61,) wall abscissae at the nodes, in units of the rod length l"),
               Port("nodes", "(61,) node heights y_i = 0.05 i l / 3, in units of l"),
               Port("area", "() converged exact area, in units of l²"),
               Port("area_positions", "() positions-only area, final grid, in units of l²"),
               Port("area_thesis", "() positions-only area with thesis_positions positions, in units of l²"),
               Port("area_grid", "() objective at the optimum, in units of l²"),
               Port("start_area", "() area of the vertical wall (3 pi l²/32), in units of l²"),
               Port("iterations", "() solver iterations"), Port("evaluations", "() area evaluations"),
               Port("seconds", "() solver time", "s"))

    def run(self, inputs: Mapping[str, Any], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        context.progress(0, 1, f"optimal wall ({params['method']})")
        r = optimal_wall(params["method"], params["l"], (params["positions"], params["strips"]),
                         (params["final_positions"], params["final_strips"]), params["objective"],
                         params["thesis_positions"], params["maxiter"],
                         progress=lambda calls: context.progress(calls, None, "area evaluations"))
        context.progress(1, 1, "done")
        return {"w": r.w, "nodes": THESIS_WALL_NODES * params["l"] / 3.0, "area": r.area,
                "area_positions": r.area_positions, "area_thesis": r.area_thesis, "area_grid": r.area_grid,
                "start_area": r.start_area, "iterations": r.iterations, "evaluations": r.evaluations,
                "seconds": r.seconds}


_BODIES = (Port("body1", "(T, m1, 3) markers of the first body (>= 3), NaN where missing", "mm"),
           Port("body2", "(T, m2, 3) markers of the second body", "mm"))


class SphericalJointAlgorithm(Algorithm):
    """Least-squares ball-joint centre between two rigid marker groups."""

    name = "spherical_joint"
    version = "0.1.0"
    description = "centre of rotation between two rigid marker groups in 3-D (a ball joint)"
    parameters = ParameterSet()
    inputs = _BODIES
    outputs = (Port("centre", "(T, 3) joint centre", "mm"), Port("local1", "(3,) in body 1's frame", "mm"),
               Port("local2", "(3,) in body 2's frame", "mm"), Port("residual", "(T,) mismatch", "mm"),
               Port("rms", "() RMS mismatch", "mm"),
               Port("condition", "() condition number of the fit (large: relative rotation near one axis)"))

    def run(self, inputs: Mapping[str, Any], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        j = spherical_joint(_array(inputs, "body1"), _array(inputs, "body2"))
        return {"centre": j.centre, "local1": j.local1, "local2": j.local2, "residual": j.residual, "rms": j.rms,
                "condition": j.condition}


class RevoluteJointAlgorithm(Algorithm):
    """Least-squares hinge axis between two rigid marker groups."""

    name = "revolute_joint"
    version = "0.1.0"
    description = "hinge axis between two rigid marker groups in 3-D, and the rotation about it"
    parameters = ParameterSet()
    inputs = _BODIES
    outputs = (Port("point", "(T, 3) axis point", "mm"), Port("direction", "(T, 3) unit axis direction"),
               Port("angle", "(T,) rotation of body 2 about the axis from frame 0", "rad"),
               Port("residual", "(T,) off-axis mismatch", "mm"), Port("rms", "() RMS mismatch", "mm"))

    def run(self, inputs: Mapping[str, Any], params: Mapping[str, Any], context: RunContext) -> dict[str, Any]:
        j = revolute_joint(_array(inputs, "body1"), _array(inputs, "body2"))
        return {"point": j.point, "direction": j.direction, "angle": j.angle, "residual": j.residual, "rms": j.rms}


ALGORITHMS = [RigidGroupsAlgorithm, FourBarAlgorithm, SweptArea, Centrodes, ArcWallGrid, OptimalWallAlgorithm,
              SphericalJointAlgorithm, RevoluteJointAlgorithm]
