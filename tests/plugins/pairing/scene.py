"""Exact mirror scenes for pairing tests: a pinhole camera, plane mirrors, markers and their images."""

from __future__ import annotations

import numpy as np
from mirrorlab.plugins.pairing import mirror_epipole, projection_matrix
from mirrorlab.plugins.photogrammetry import PinholeCamera, reflect

K = np.array([[1000.0, 0.0, 640.0], [0.0, 1000.0, 480.0], [0.0, 0.0, 1.0]])
CAMERA = PinholeCamera(K, np.zeros(5), np.eye(3), np.zeros(3))  # at the origin, looking along +Z
P = projection_matrix(K, np.eye(3), np.zeros(3))


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


#: (mirror point G, normal toward the camera): behind the markers (virtual camera in front of the
#: camera), to the left, and to the right facing partly forward (virtual camera behind the camera).
MIRRORS = [
    (np.array([0.0, 0.0, 2000.0]), _unit([-0.5, 0.0, -1.0])),
    (np.array([-900.0, 0.0, 1000.0]), _unit([1.0, 0.1, -0.25])),
    (np.array([1000.0, 0.0, 500.0]), _unit([-1.0, 0.0, 0.3])),
]


def epipoles(mirrors=MIRRORS) -> np.ndarray:
    return np.array([mirror_epipole(P, CAMERA.camera_center, g, n) for g, n in mirrors])


def markers(rng: np.random.Generator, n: int, mirrors=MIRRORS) -> np.ndarray:
    """n points in front of the camera and of every mirror, whose images fall on a wide sensor."""
    out = []
    while len(out) < n:
        x = rng.uniform([-400, -300, 800], [400, 300, 1500])
        if all((x - g) @ nn > 50 for g, nn in mirrors) and all(
                reflect(x, g, nn)[2] > 100 for g, nn in mirrors):
            out.append(x)
    return np.array(out)


def images(points: np.ndarray, mirrors=MIRRORS):
    """Real images (N, 2) and, per mirror, the mirror images (N, 2) — exact pixels."""
    real = CAMERA.project(points)
    virtual = [CAMERA.project(reflect(points, g, nn)) for g, nn in mirrors]
    return real, virtual
