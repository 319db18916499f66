"""``VirtualLab``: a scene, a camera, mirrors and a renderer; frames, truth and films.

:func:`make_lab` builds the preset laboratories by scene name (:data:`SCENE_NAMES`).
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .optics import LabCamera, Mirror, calibration_grid, look_at_camera
from .render import Renderer, RenderSettings, outline_circles
from .scenes import BoxScene, FourBarScene, GridScene, Placement, RSSRScene, Scene, UpperLimbScene
from .truth import LabTruth, compute_truth

__all__ = ["SCENE_NAMES", "VirtualLab", "make_lab"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class Outlines:
    """Projected marker outlines of one frame: ``polygons`` (Q, N, 2) px, grey ``levels`` (Q,),
    ``view`` (Q,) (-1 direct, k mirror k) and ``marker`` (Q,) index."""

    polygons: FloatArray
    levels: FloatArray
    view: NDArray[np.int64]
    marker: NDArray[np.int64]


@dataclass(frozen=True)
class VirtualLab:
    """A simulated experiment: ``scene`` filmed by ``camera`` directly and in ``mirrors``.

    Examples
    --------
    >>> lab = make_lab("rssr", image_size=(600, 400))
    >>> frame = lab.render(0.0)
    >>> frame.shape, frame.dtype, int(frame.max()) > 200
    ((400, 600), dtype('uint8'), True)
    """

    scene: Scene
    camera: LabCamera
    mirrors: tuple[Mirror, ...] = ()
    settings: RenderSettings = field(default_factory=RenderSettings)

    @cached_property
    def renderer(self) -> Renderer:
        assert self.camera.image_size is not None
        return Renderer(self.camera.image_size, self.settings)

    def with_scene(self, scene: Scene) -> VirtualLab:
        """The same camera, mirrors and look with another scene (e.g. the calibration grid)."""
        return replace(self, scene=scene)

    def with_settings(self, **changes: object) -> VirtualLab:
        """The same lab with changed :class:`RenderSettings` fields."""
        return replace(self, settings=replace(self.settings, **changes))

    # -- truth -------------------------------------------------------------------------------------
    def truth(self, times: ArrayLike) -> LabTruth:
        """Ground truth at ``times`` (s)."""
        return compute_truth(self.scene, self.camera, self.mirrors, times)

    def outlines(self, truth: LabTruth, k: int) -> Outlines:
        """Projected outlines of the markers visible in frame ``k`` of ``truth`` (all views at once)."""
        C = self.camera.camera_center
        pos, nrm, radii = truth.positions[k], truth.normals[k], truth.radii
        pts, levels, views, markers = [], [], [], []
        viewpoints = [(-1, C, truth.real_visible[k], None)]
        for j, m in enumerate(self.mirrors):
            viewpoints.append((j, m.virtual_centre(C), truth.virtual_visible[k, j], m))
        for view, eye, visible, mirror in viewpoints:
            idx = np.flatnonzero(visible)
            if idx.size == 0:
                continue
            c, n, r = pos[idx], nrm[idx].copy(), radii[idx].copy()
            sphere = np.isnan(n).any(axis=1)
            if sphere.any():       # silhouette circle of a ball seen from `eye`
                to_eye = eye - c[sphere]
                d = np.linalg.norm(to_eye, axis=1)
                u = to_eye / d[:, None]
                rs = r[sphere]
                c = c.copy()
                c[sphere] = c[sphere] + (rs**2 / d)[:, None] * u
                r[sphere] = rs * np.sqrt(np.clip(1 - (rs / d) ** 2, 0.0, 1.0))
                n[sphere] = u
            ring = outline_circles(c, n, r, self.settings.outline_points)
            if mirror is not None:
                ring = mirror.reflect(ring)
            pts.append(ring)
            gain = 1.0 if mirror is None else self.settings.mirror_reflectance
            levels.append(np.full(idx.size, self.settings.marker * gain))
            views.append(np.full(idx.size, view))
            markers.append(idx)
        N = self.settings.outline_points
        if not pts:
            return Outlines(np.zeros((0, N, 2)), np.zeros(0), np.zeros(0, np.int64), np.zeros(0, np.int64))
        ring3 = np.concatenate(pts)
        poly = self.camera.project(ring3.reshape(-1, 3)).reshape(-1, N, 2)
        return Outlines(poly, np.concatenate(levels), np.concatenate(views).astype(np.int64),
                        np.concatenate(markers).astype(np.int64))

    # -- frames ------------------------------------------------------------------------------------
    def render_truth(self, truth: LabTruth, k: int, index: int | None = None) -> NDArray[np.uint8]:
        """Render frame ``k`` of an already computed ``truth`` (noise seeded by ``index``, default k)."""
        o = self.outlines(truth, k)
        return self.renderer.render(o.polygons, o.levels, k if index is None else index)

    def render(self, t: float, index: int = 0) -> NDArray[np.uint8]:
        """The grey frame (H, W) uint8 at time ``t`` (s); ``index`` seeds its noise."""
        return self.render_truth(self.truth([t]), 0, index)

    def frames(self, times: ArrayLike) -> Iterator[tuple[float, NDArray[np.uint8]]]:
        """Yield ``(t, frame)`` for each time (s); frame ``k``'s noise is seeded by ``k``."""
        tt = np.atleast_1d(np.asarray(times, dtype=float))
        truth = self.truth(tt)
        for k in range(tt.size):
            yield float(tt[k]), self.render_truth(truth, k)


# ----------------------------------------------------------------------------------------- presets
#: Scene names accepted by :func:`make_lab`: the one list (the film scanner's ``scene`` setting uses it).
SCENE_NAMES = ("rssr", "four_bar", "box", "upper_limb", "grid")

#: Thesis RSSR experiment (photogrammetry.md §10): camera principal point F1 and mirror point G, mm.
THESIS_F1 = (435.68, 202.6, 1442.024)
THESIS_G = (-291.62, -52.76, 487.56)
THESIS_NORMAL = (np.cos(np.deg2rad(50.0)), 0.0, np.sin(np.deg2rad(50.0)))


def make_lab(name: str, image_size: tuple[int, int] | None = None, settings: RenderSettings | None = None,
             distortion: Sequence[float] = (0.0, 0.0, 0.0, 0.0, 0.0)) -> VirtualLab:
    """A preset virtual laboratory.

    * ``rssr``: the thesis RSSR mirror experiment (§3.6.1): camera at F1 = (435.68, 202.6, 1442.024)
      mm, 30 mm lens on 36 x 24 mm, aimed at the calibration plane Z = 0; 1 m x 1 m mirror through
      G = (-291.62, -52.76, 487.56) with normal (cos 50°, 0, sin 50°); the mechanism above the plane
      so that both markers are seen directly and in the mirror over the whole revolution.
    * ``grid``: the same camera with the 60 mm calibration grid on Z = 0 (41 x 27 discs of 8 mm
      radius filling the frame); the calibration exposure is taken without the mirror, whose back
      would hide part of the grid.
    * ``four_bar``: the planar four-bar (§5.5) on z = 0 seen from 1.2 m, 35 mm cine frame, no mirror.
    * ``box``: the box thrown in front of a vertical 2 m x 2 m mirror (§3.6.2), cine frame.
    * ``upper_limb``: the arm lifting the bar, 1 m x 1 m mirror beside the subject (§6.3.2).

    Parameters
    ----------
    name : one of :data:`SCENE_NAMES`.
    image_size : (width, height) px; default 1800 x 1200 (36 x 24 mm) or 1600 x 1200 (cine 24 x 18).
    settings : RenderSettings (default: clean frames).
    distortion : OpenCV coefficients (k1, k2, p1, p2, k3) of the camera.

    Raises
    ------
    ValueError
        Unknown name.
    """
    s = settings or RenderSettings()
    if name in ("rssr", "grid"):
        size = image_size or (1800, 1200)
        camera = look_at_camera(THESIS_F1, (-150.0, -60.0, 0.0), 30.0, (36.0, 24.0), size, distortion=distortion)
        mirror = Mirror(THESIS_G, THESIS_NORMAL, 1000.0, 1000.0)
        scene: Scene
        if name == "rssr":
            scene = RSSRScene(placement=Placement.from_euler((0.0, 0.0, 0.0), (300.0, -100.0, 700.0)))
        else:
            return VirtualLab(GridScene(calibration_grid(60.0, (41, 27), (-240.0, -60.0))), camera, (), s)
        return VirtualLab(scene, camera, (mirror,), s)
    if name == "four_bar":
        size = image_size or (1600, 1200)
        camera = look_at_camera((115.0, -20.0, 1200.0), (115.0, -20.0, 0.0), 50.0, (24.0, 18.0), size,
                                distortion=distortion)
        return VirtualLab(FourBarScene(), camera, (), s)
    if name == "box":
        size = image_size or (1600, 1200)
        camera = look_at_camera((300.0, 300.0, 3200.0), (-250.0, 250.0, 0.0), 25.0, (24.0, 18.0), size,
                                distortion=distortion)
        mirror = Mirror((-1100.0, 500.0, -300.0), (np.cos(np.deg2rad(40.0)), 0.0, np.sin(np.deg2rad(40.0))),
                        2000.0, 2000.0)
        return VirtualLab(BoxScene(), camera, (mirror,), s)
    if name == "upper_limb":
        size = image_size or (1600, 1200)
        camera = look_at_camera((400.0, 1300.0, 2300.0), (150.0, 1150.0, 0.0), 25.0, (24.0, 18.0), size,
                                distortion=distortion)
        mirror = Mirror((-500.0, 1150.0, -200.0), (np.cos(np.deg2rad(45.0)), 0.0, np.sin(np.deg2rad(45.0))),
                        1000.0, 1000.0)
        return VirtualLab(UpperLimbScene(), camera, (mirror,), s)
    raise ValueError(f"unknown virtual-lab scene {name!r}; choose one of {', '.join(SCENE_NAMES)}")
