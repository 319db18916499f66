"""Noiseless synthetic scenes (thesis §10 geometry) shared by the plugin tests."""

from __future__ import annotations

import numpy as np
from mirrorlab.plugins.photogrammetry.cameras import PinholeCamera
from mirrorlab.plugins.photogrammetry.mirror import reflect
from mirrorlab.plugins.photogrammetry.sensitivity import THESIS_F1, THESIS_G, THESIS_GRID_X, THESIS_GRID_Y, MirrorScene

F1, G = THESIS_F1, THESIS_G
NORMAL = np.array([np.cos(np.radians(50.0)), 0.0, np.sin(np.radians(50.0))])
FOCAL = 30.0


def grid_points() -> tuple[np.ndarray, np.ndarray]:
    """The 91 calibration points: film coordinates (mm, film parallel to Z = 0) and plane X, Y (mm)."""
    grid = np.stack(np.meshgrid(THESIS_GRID_X, THESIS_GRID_Y, indexing="ij"), axis=-1).reshape(-1, 2)
    d = np.c_[grid, np.zeros(len(grid))] - F1
    film = FOCAL * np.c_[d[:, 0], -d[:, 1]] / -d[:, 2:3]
    return film, grid


def markers(frames: int, per_frame: int, seed: int = 0) -> np.ndarray:
    """(frames, markers, 3) mm in front of the mirror (reflecting side), inside the camera's view."""
    rng = np.random.default_rng(seed)
    pts = rng.uniform([-100, -100, 150], [300, 200, 450], size=(4 * frames * per_frame, 3))
    pts = pts[(pts - G) @ NORMAL > 30.0][: frames * per_frame]
    return pts.reshape(frames, per_frame, 3)


def plane_images(points: np.ndarray, normal: np.ndarray = NORMAL) -> tuple[np.ndarray, np.ndarray]:
    """Direct and mirror film coordinates (frames, markers, 2) through the thesis plane calibration."""
    scene = MirrorScene.thesis(float(np.arctan2(normal[2], normal[0])), FOCAL)
    flat = points.reshape(-1, 3)
    U, V = scene.image_points(flat)
    return U.reshape(points.shape[:-1] + (2,)), V.reshape(points.shape[:-1] + (2,))


def pinhole_camera() -> PinholeCamera:
    """A 1920x1080 pinhole at F1 aimed between the markers and their mirror images, with distortion."""
    target = 0.5 * (np.array([100.0, 50.0, 300.0]) + reflect(np.array([100.0, 50.0, 300.0]), G, NORMAL))
    z = (target - F1) / np.linalg.norm(target - F1)
    x = np.cross([0.0, 1.0, 0.0], z)
    x /= np.linalg.norm(x)
    R = np.stack([x, np.cross(z, x), z])
    K = np.array([[1400.0, 0, 960], [0, 1400.0, 540], [0, 0, 1]])
    return PinholeCamera(K, np.array([-0.05, 0.01, 0.0, 0.0, 0.0]), R, -R @ F1)
