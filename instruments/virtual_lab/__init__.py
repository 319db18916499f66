"""The virtual lab: simulated experiments with exact ground truth (issue [demo] item 1).

Rigid bodies carrying circular markers (:mod:`.scenes`), a pinhole camera with tilt and lens
distortion and finite plane mirrors (:mod:`.optics`, the lab's own optics, independent of the
photogrammetry plugin they validate), an OpenCV renderer (:mod:`.render`) and the
per-frame ground truth (:mod:`.truth`), tied together by :class:`VirtualLab` (:mod:`.lab`). The
lab is a direct frame source (:meth:`VirtualLab.frames`) and the film of the FSCAN simulator
(:meth:`VirtualLab.film`). Units: mm, s, rad, px.

The package is also what the other simulators share, importing only the core: the tracking
world and its ``SIM:LOAD`` (:mod:`.world`, :mod:`.worlds`), the line-sensor detector
(:mod:`.line_sensor`), the device models' seeded noise and fault usage (:mod:`.simulators`) and the
trackers' experiment and figure helpers (:mod:`.experiments`, :mod:`.figures`).
"""

from .lab import SCENE_NAMES, Outlines, VirtualLab, make_lab
from .optics import LabCamera, Mirror, Views, calibration_grid, camera_frame, look_at_camera, thesis_grid_points, view_points
from .render import Renderer, RenderSettings, outline_circles
from .scenes import BoxScene, FourBarScene, GridScene, Placement, RSSRScene, Scene, SceneState, UpperLimbScene
from .truth import LabTruth, compute_truth, write_truth

__all__ = ["SCENE_NAMES", "BoxScene", "FourBarScene", "GridScene", "LabCamera", "LabTruth", "Mirror", "Outlines",
           "Placement", "RSSRScene", "Renderer", "RenderSettings", "Scene", "SceneState", "UpperLimbScene",
           "Views", "VirtualLab", "calibration_grid", "camera_frame", "compute_truth", "look_at_camera",
           "make_lab", "outline_circles", "thesis_grid_points", "view_points", "write_truth"]
