"""The film scanner on the virtual lab: its frame source and film, and the lab's truth in the session.

The film scanner depends on the virtual lab, never the other way round (the lab knows nothing of
films or scanners).

* :class:`VirtualSource`: a :class:`~mirrorlab.instruments.film_scanner.sources.FrameSource` that
  renders frame ``k`` of a preset lab at scene time ``k / frame_rate`` (``source = "virtual"``).
* :func:`lab_film`: the frames of a lab at given times as a film strip; :func:`virtual_film`: the
  film of a preset lab for the FSCAN simulator.
* :func:`record_truth`: writes the truth of the frames an instrument recorded to
  ``/truth/<label>/``; :func:`record_all_truth` does it for every virtual-lab film scanner of a
  session, and the film scanner's plugin calls it from the ``mirrorlab_recording_stopped`` hook.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from mirrorlab.core import DeviceDisconnected
from mirrorlab.core.devices import Identity
from mirrorlab.instruments.virtual_lab import SCENE_NAMES, VirtualLab, make_lab, write_truth
from numpy.typing import ArrayLike, NDArray

from .film import FRAME_H_MM, FRAME_W_MM, OVERSAMPLE, TEX_H, TEX_W, Film, Marker
from .sources import FrameSource
from .wire import PIXELS

__all__ = ["FILM_EDGE_LINES", "FILM_SIZE", "SCAN_FRAME_LINES", "SOURCE_SIZE", "VirtualSource", "lab_film",
           "record_all_truth", "record_truth", "scan_first_line", "scene_lab", "virtual_film"]

#: Render size of the direct source (4:3, resized by the scanner to 512 x 384).
SOURCE_SIZE = (1024, 768)
#: Render size of a film frame: the film texture itself (24 mm x 18 mm at 4 x the scan pitch).
FILM_SIZE = (TEX_W, TEX_H)
#: Scan lines of a whole 18 mm film frame (the direct source is resized to 512 x this).
SCAN_FRAME_LINES = TEX_H // OVERSAMPLE
#: Dark frame edge of a virtual film, in scan lines: the top lines of every frame are unexposed, as
#: the FSCAN heading needs (it stops at the first whole dark line after the clear inter-frame band).
#: A scene whose top rows are bright (the calibration grid fills the frame) would otherwise be
#: headed wherever its first all-dark line happens to be (89 lines into the grid frame).
FILM_EDGE_LINES = 4


def scene_lab(scene: str, image_size: tuple[int, int]) -> VirtualLab:
    """The preset lab for a ``scene`` setting, with a light clean look (dark background)."""
    if scene not in SCENE_NAMES:
        raise DeviceDisconnected(f"unknown virtual-lab scene {scene!r}; set `scene` to one of "
                                 f"{', '.join(SCENE_NAMES)}")
    return make_lab(scene, image_size=image_size)


def lab_film(lab: VirtualLab, times: ArrayLike) -> Film:
    """A film strip of ``lab``'s frames at ``times`` (s) for the FSCAN simulator.

    Frames are rendered lazily (:class:`Film` with a generator); each is stretched over the
    24 mm x 18 mm cine frame, so give the camera a 4:3 image (e.g. 2048 x 1536, the film
    texture size) to keep the aspect. The film's marker truth (``SIM:TRUTH?``) lists every
    visible image: ``ident = view * M + marker`` with view 0 = direct, k + 1 = mirror k.
    """
    tt = np.atleast_1d(np.asarray(times, dtype=float))
    truth = lab.truth(tt)
    w, h = lab.camera.image_size or (1, 1)
    M = len(truth.labels)
    markers: list[Marker] = []
    for k in range(tt.size):
        o = lab.outlines(truth, k)
        xy, views = truth.view_xy()
        for view, m, poly in zip(o.view, o.marker, o.polygons):
            x, y = xy[k, view + 1, m]
            area = 0.5 * abs(np.dot(poly[:, 0], np.roll(poly[:, 1], 1)) - np.dot(poly[:, 1], np.roll(poly[:, 0], 1)))
            markers.append(Marker(k, int((view + 1) * M + m), (x + 0.5) / w * FRAME_W_MM - FRAME_W_MM / 2,
                                  (y + 0.5) / h * FRAME_H_MM, float(np.sqrt(area / np.pi)) / w * FRAME_W_MM))
    return Film(generator=lambda k: lab.render_truth(truth, k), n_frames=tt.size, markers=markers)


def virtual_film(scene: str, frame_rate: float, n_frames: int) -> Film:
    """A film of ``n_frames`` frames of ``scene`` shot at ``frame_rate`` (Hz), frame k at t = k / rate.

    Frames are rendered at :data:`FILM_SIZE`; their top :data:`FILM_EDGE_LINES` scan lines are
    dark (unexposed frame edge), so the scanner's heading finds every frame at its top edge
    whatever the scene shows there.

    Examples
    --------
    >>> film = virtual_film("rssr", 3.0, 2)
    >>> film.n_frames, len(film.markers)
    (2, 8)
    """
    lab = scene_lab(scene, FILM_SIZE)
    film = lab_film(lab, np.arange(n_frames) / float(frame_rate))
    edge = FILM_EDGE_LINES * OVERSAMPLE

    def exposed(k: int) -> NDArray[np.uint8]:
        img = np.array(film.image(k), dtype=np.uint8)
        img[:edge] = 0                      # the dark frame edge the heading looks for
        return img

    return Film(generator=exposed, n_frames=film.n_frames, markers=film.markers)


class VirtualSource(FrameSource):
    """Rendered frames of a preset virtual lab: frame ``k`` shows scene time ``k / frame_rate``.

    The source ends after ``n_frames`` (0 = endless) or when a finite scene (the box flight) is over.

    Examples
    --------
    >>> src = VirtualSource("rssr", 3.0, 2); src.open()
    >>> [(i, img.shape) for i, img in iter(src.read, None)]
    [(0, (768, 1024)), (1, (768, 1024))]
    """

    kind = "VIRTUAL"

    def __init__(self, scene: str, frame_rate: float, n_frames: int = 0,
                 image_size: tuple[int, int] = SOURCE_SIZE) -> None:
        self.scene = scene
        self.frame_rate = float(frame_rate)
        self.n_frames = int(n_frames)
        self.image_size = image_size
        self.lab: VirtualLab | None = None
        self._next = 0

    def open(self) -> None:
        self.lab = scene_lab(self.scene, self.image_size)
        self._next = 0

    def read(self) -> tuple[int, NDArray[np.uint8]] | None:
        if self.lab is None:
            raise DeviceDisconnected("virtual source is not open; connect first")
        k = self._next
        t = k / self.frame_rate
        duration = self.lab.scene.duration
        if (self.n_frames and k >= self.n_frames) or (duration is not None and t > duration):
            return None
        self._next += 1
        return k, self.lab.render_truth(self.lab.truth([t]), 0, index=k)

    def rewind(self) -> None:
        self._next = 0

    def close(self) -> None:
        self.lab = None

    def identity(self) -> Identity:
        return Identity(self.kind, "mirrorlab", "virtual_lab", self.scene, f"{self.frame_rate:g} Hz")


def scan_first_line(source: str, lines: int, head_skip: int) -> int:
    """The film line (of the :data:`SCAN_FRAME_LINES` of a whole frame) that is row 0 of the scanned frame.

    ``source = "virtual"`` keeps the central ``lines`` of the resized frame; the FSCAN digitiser
    starts ``head_skip`` lines after the frame's top edge found by heading (nominally: heading's
    own error is part of the digitising error).

    Examples
    --------
    >>> scan_first_line("virtual", 344, 37), scan_first_line("fscan", 344, 37)
    (20, 37)
    """
    return (SCAN_FRAME_LINES - int(lines)) // 2 if source == "virtual" else int(head_skip)


def record_truth(session: Any, label: str) -> str | None:
    """Write the ground truth of the frames instrument ``label`` recorded to ``/truth/<label>/``.

    Applies to a ``film_scanner`` with ``source = "virtual"``, or a simulated ``fscan`` whose film
    is a virtual-lab scene. Frame ``k`` (the ``frame_index`` stream) shows scene time
    ``k / frame_rate``; the truth is in the render geometry of that path (px of the
    :data:`SOURCE_SIZE` or :data:`FILM_SIZE` image). The attributes ``scan_width``,
    ``scan_frame_lines`` and ``scan_first_line`` say how those pixels map to the recorded
    (scanner) frames: ``col = (x + 0.5) * scan_width / image_width - 0.5``, ``row = (y + 0.5) *
    scan_frame_lines / image_height - 0.5 - scan_first_line``. Returns the group path, or ``None``
    when the instrument is not on the virtual lab or recorded no frame.
    """
    inst = session.instruments[label]
    settings = inst.settings
    scene = settings.get("scene", "")
    source = settings.get("source", "")
    simulated = bool(session.attributes(f"instruments/{label}").get("simulated", False))
    if not scene or not (source == "virtual" or (source == "fscan" and simulated)):
        return None
    if not session.exists(f"instruments/{label}/frame_index"):
        return None
    index = np.asarray(session.stream(label, "frame_index").data, dtype=np.int64)
    if index.size == 0:
        return None
    size = SOURCE_SIZE if source == "virtual" else FILM_SIZE
    lab = scene_lab(scene, size)
    times = index / float(settings["frame_rate"])
    truth = lab.truth(times)
    return write_truth(session, label, truth, lab.camera, lab.mirrors, frame_index=index,
                       attrs={"instrument": label, "source": source, "frame_rate_hz": float(settings["frame_rate"]),
                              "image_width": size[0], "image_height": size[1], "scan_width": PIXELS,
                              "scan_frame_lines": SCAN_FRAME_LINES,
                              "scan_first_line": scan_first_line(source, settings.get("lines", 344),
                                                                 settings.get("head_skip", 37))})


def record_all_truth(session: Any) -> None:
    """Record the virtual-lab truth of every film scanner of ``session`` (called when recording stops)."""
    for label, inst in session.instruments.items():
        if getattr(inst, "name", "") == "film_scanner" and not session.exists(f"truth/{label}"):
            record_truth(session, label)
