"""Ground truth of the virtual lab per frame, and its place in a session file (``/truth/<name>``).

Truth is kept apart from measurements: :func:`write_truth` writes only under ``/truth/``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .optics import LabCamera, Mirror, Views, view_points
from .scenes import Scene, SceneState

__all__ = ["LabTruth", "compute_truth", "write_truth"]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LabTruth:
    """Exact 3-D and image positions of every marker in every frame.

    Attributes
    ----------
    scene : scene name.
    labels : (M,) marker names.
    radii : (M,) marker radii, mm.
    time : (T,) s.
    positions : (T, M, 3) mm.
    normals : (T, M, 3) marker normals (NaN rows: spherical markers).
    real_xy : (T, M, 2) px of the direct images, NaN where not visible.
    real_visible : (T, M) bool.
    virtual_xy : (T, K, M, 2) px of the mirror images in mirror k, NaN where not visible.
    virtual_visible : (T, K, M) bool.
    virtual_points : (T, K, M, 3) mm, the reflected (virtual) markers.
    mirror_id : (T, M) int, the first mirror in which the marker is seen, -1 for none.
    analytic : name -> array, the scene's exact quantities.
    """

    scene: str
    labels: tuple[str, ...]
    radii: FloatArray
    time: FloatArray
    positions: FloatArray
    normals: FloatArray
    real_xy: FloatArray
    real_visible: NDArray[np.bool_]
    virtual_xy: FloatArray
    virtual_visible: NDArray[np.bool_]
    virtual_points: FloatArray
    mirror_id: NDArray[np.int64]
    analytic: dict[str, FloatArray]

    @property
    def n_frames(self) -> int:
        return int(self.time.size)

    def view_xy(self) -> tuple[FloatArray, NDArray[np.int64]]:
        """All views stacked: image positions ``(T, 1 + K, M, 2)`` and the mirror id per view
        ``(1 + K,)`` (-1 = direct view, k = mirror k)."""
        xy = np.concatenate([self.real_xy[:, None], self.virtual_xy], axis=1)
        return xy, np.arange(-1, self.virtual_xy.shape[1], dtype=np.int64)


def compute_truth(scene: Scene, camera: LabCamera, mirrors: Sequence[Mirror], times: ArrayLike,
                  state: SceneState | None = None) -> LabTruth:
    """Ground truth of ``scene`` seen by ``camera`` directly and in ``mirrors`` at ``times`` (s).

    Examples
    --------
    >>> from mirrorlab.instruments.virtual_lab import make_lab
    >>> lab = make_lab("rssr")
    >>> tr = compute_truth(lab.scene, lab.camera, lab.mirrors, [0.0, 1.0])
    >>> tr.real_xy.shape, tr.virtual_xy.shape, bool(tr.real_visible.all() and tr.virtual_visible.all())
    ((2, 2, 2), (2, 1, 2, 2), True)
    """
    st = scene.state(times) if state is None else state
    C = camera.camera_center
    hidden_real = scene.occluded(st, C)
    hidden_virtual = np.stack([scene.occluded(st, m.virtual_centre(C)) for m in mirrors], axis=1) \
        if mirrors else None
    v: Views = view_points(camera, mirrors, st.positions, st.normals, hidden_real, hidden_virtual)
    seen = v.virtual_visible
    mirror_id = (np.where(seen.any(axis=1), np.argmax(seen, axis=1), -1) if seen.shape[1] else
                 np.full(seen.shape[::2], -1)).astype(np.int64)
    return LabTruth(scene.name, tuple(scene.labels), np.asarray(scene.radii, float), st.t, st.positions,
                    st.normals, v.real_xy, v.real_visible, v.virtual_xy, v.virtual_visible, v.virtual_points,
                    mirror_id, dict(st.analytic))


def write_truth(session: Any, name: str, truth: LabTruth, camera: LabCamera | None = None,
                mirrors: Sequence[Mirror] = (), attrs: dict[str, Any] | None = None,
                frame_index: ArrayLike | None = None) -> str:
    """Write ``truth`` to ``session`` under ``/truth/<name>/`` (never among the measurements).

    Groups: ``markers`` (time, positions, normals, real/virtual image positions and visibility,
    mirror_id, radii, labels, optional frame_index), ``analytic`` (the scene's exact quantities),
    ``camera`` (K, dist, R, t, image_size, centre) and ``mirrors`` (centre, normal, size) when given.
    Units: mm, s, rad, px. Returns the group path.

    Raises
    ------
    SessionError
        The group exists already, or the session is read-only or recording.
    """
    root = f"truth/{name}"
    markers = {"time": truth.time, "positions": truth.positions, "normals": truth.normals,
               "real_xy": truth.real_xy, "real_visible": truth.real_visible, "virtual_xy": truth.virtual_xy,
               "virtual_visible": truth.virtual_visible, "virtual_points": truth.virtual_points,
               "mirror_id": truth.mirror_id, "radii": truth.radii,
               "labels": np.array(truth.labels, dtype="S")}
    if frame_index is not None:
        markers["frame_index"] = np.asarray(frame_index, dtype=np.int64)
    meta = {"scene": truth.scene, "units": "mm, s, rad, px", "kind": "ground truth (virtual lab)",
            "description": "real_xy (T, M, 2) and virtual_xy (T, K, M, 2) in px, NaN where not visible",
            **(attrs or {})}
    session.write_group(f"{root}/markers", markers, meta)
    session.write_group(f"{root}/analytic", {k: np.asarray(v) for k, v in truth.analytic.items()},
                        {"scene": truth.scene})
    if camera is not None:
        session.write_group(f"{root}/camera", {
            "K": camera.K, "dist": camera.dist, "R": camera.R, "t": camera.t, "centre": camera.camera_center,
            "image_size": np.asarray(camera.image_size if camera.image_size else (0, 0), dtype=np.int64)})
    if mirrors:
        session.write_group(f"{root}/mirrors", {
            "centre": np.array([m.centre for m in mirrors]), "normal": np.array([m.normal for m in mirrors]),
            "size": np.array([[m.width, m.height] for m in mirrors]),
            "virtual_centre": np.array([m.virtual_centre(camera.camera_center) for m in mirrors])
            if camera is not None else np.zeros((len(mirrors), 3))})
    return "/" + root
