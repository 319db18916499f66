"""The thesis's thrown-box experiment in the virtual lab (``kinematics.md`` §5, Fig. 3.30).

A 200 x 200 x 300 mm, 2.2 kg box with a marker at each vertex is thrown up in front of a vertical
2 m x 2 m plane mirror and filmed by one 16 mm cine camera (42 frames/s): :func:`thesis_box_lab`.
The measurement chain run on it (mirror triangulation, rigid fit, angular momentum) uses the
photogrammetry and kinematics plugins, so it lives with its tests
(``tests/plugins/kinematics/experiments/box_flight.py``, reported by ``docs/validation/box_flight.py``).
Units: mm, s, rad, px. World frame: Y up, floor at Y = 0.
"""

from __future__ import annotations

import numpy as np

from .lab import VirtualLab
from .optics import Mirror, look_at_camera
from .render import RenderSettings
from .scenes import BoxScene

__all__ = ["CINE_16MM_FRAME_MM", "THESIS_BOX_RATE", "THESIS_FILM_SIGMA_MM", "thesis_box_lab"]

#: Frame rate of the thesis's cine film of the thrown box (frames/s).
THESIS_BOX_RATE = 42.0
#: Image area of a 16 mm cine frame (width, height), mm.
CINE_16MM_FRAME_MM = (10.26, 7.49)
#: Digitising noise on the film (mm, 1 sigma per coordinate): the 0.003 mm film perturbation of
#: Table 3.1, about one 0.05 mm digitiser count on a 16 mm frame enlarged ~17 times.
THESIS_FILM_SIGMA_MM = 0.003


def thesis_box_lab(mirror_height: float = 2000.0, focal_mm: float = 10.0, px_per_mm: float = 100.0,
                   centre0: tuple[float, float, float] = (-500.0, 1000.0, 0.0),
                   velocity0: tuple[float, float, float] = (500.0, 4900.0, 0.0),
                   omega0_body: tuple[float, float, float] = (3.0, 1.0, 6.0),
                   duration: float = 1.0) -> VirtualLab:
    """A thesis-like laboratory for the thrown box (``kinematics.md`` §5, ``photogrammetry.md`` §10).

    Choices (the thesis prints none of the distances): floor at Y = 0; a vertical mirror
    ``2000 mm`` wide and ``mirror_height`` high standing on the floor, centre (-1300, h/2, -300) mm,
    normal (cos 40°, 0, sin 40°) (the arrangement of ``make_lab("box")``); a 16 mm cine camera
    (10.26 x 7.49 mm frame, ``focal_mm`` lens) on a tripod at (300, 1200, 3800) mm aimed at
    (-400, 1500, 0) mm, so that the box and its mirror image stay in the frame; the box thrown
    from hand height (centre 1 m above the floor) with 4.9 m/s upward, i.e. a 1 s flight whose apex
    (2.22 m) is just above the 2 m mirror.

    Parameters
    ----------
    mirror_height : float, mm
        Height of the mirror (its bottom edge stays on the floor).
    focal_mm : float, mm
        Lens focal length.
    px_per_mm : float
        Film resolution of the simulated digitised image (px per mm of film).
    centre0, velocity0 : (3,) mm and mm/s
        Box centre and velocity at release (gravity along -Y).
    omega0_body : (3,) rad/s
        Body rate at release (body x, y along the 200 mm edges, z along the 300 mm edge).
    duration : float, s
        Length of the flight.

    Returns
    -------
    VirtualLab

    Examples
    --------
    >>> lab = thesis_box_lab()
    >>> lab.camera.image_size, float(lab.mirrors[0].corners()[:, 1].min())
    ((1026, 749), 0.0)
    """
    w, h = CINE_16MM_FRAME_MM
    size = (int(round(w * px_per_mm)), int(round(h * px_per_mm)))
    camera = look_at_camera((300.0, 1200.0, 3800.0), (-400.0, 1500.0, 0.0), focal_mm, (w, h), size)
    a = np.deg2rad(40.0)
    mirror = Mirror((-1300.0, 0.5 * mirror_height, -300.0), (np.cos(a), 0.0, np.sin(a)), 2000.0, mirror_height)
    scene = BoxScene(omega0_body=omega0_body, centre0=centre0, velocity0=velocity0, duration=duration)
    return VirtualLab(scene, camera, (mirror,), RenderSettings())
