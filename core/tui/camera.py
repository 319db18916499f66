"""The camera view: the newest frame of an image stream as half-block characters (rich-pixels),
with the detected markers (red) and their mirror pairs (a cyan line to the mirror image) drawn on it.

Markers are detected on the shown frame, in a worker, by the registry's marker detector: the
algorithm that declares the role ``marker_detector`` (input ``frames``, output ``xy`` in px, see
:data:`mirrorlab.core.algorithms.ROLES`), whichever plugin provides it. Mirror pairs come from
the newest stored result with outputs ``real`` and ``paired`` (frames, markers, [mirrors,] 2) px of
the same frame count. A live session shows its newest frame while it acquires (4 times a second);
otherwise, and in a session file, the recorded frames are shown (← → step, home/end).
Units: pixels, x right, y down.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, cast

import numpy as np
from PIL import Image, ImageDraw
from rich.text import Text
from rich_pixels import Pixels
from textual.app import ComposeResult
from textual.binding import Binding
from textual.screen import Screen
from textual.widgets import Header, Static

from ..algorithms import Algorithm, RunContext, execute
from . import browse
from .widgets import KeysFooter

if TYPE_CHECKING:
    from ..registry import Registry
    from ..session import Session
    from .app import MirrorlabApp
    from .model import Console

#: Live frame refreshes per second.
FRAME_HZ = 4
#: The role (:data:`mirrorlab.core.algorithms.ROLES`) of the algorithm that finds the markers drawn.
MARKER_DETECTOR = "marker_detector"
MARKER = (255, 40, 40)
PAIR = (0, 220, 255)


def detector(registry: Registry) -> type[Algorithm] | None:
    """The registered marker detector (the algorithm declaring the role ``marker_detector``), if any."""
    for name in registry.names("algorithm"):
        cls = registry.algorithm(name)
        if MARKER_DETECTOR in cls.roles:
            return cls
    return None


def detect(cls: type[Algorithm], frame: np.ndarray) -> np.ndarray:
    """Marker centres ``(K, 2)`` px of one frame (empty if the detector found none or failed)."""
    outcome = execute(cls, {"frames": frame[None]}, {}, RunContext())
    xy = np.asarray(outcome.outputs.get("xy", np.empty((1, 0, 2))), dtype=float)
    return xy[0][np.isfinite(xy[0]).all(axis=-1)] if xy.ndim == 3 else np.empty((0, 2))


def stored_pairs(session: Session, frames: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``real (F, N, 2)`` and ``paired (F, N, E, 2)`` px of the newest result that has both, for
    ``frames`` frames, or ``None``."""
    runs = [r.path for r in session.results()]
    for path in reversed(runs):
        if {"real", "paired"} <= set(session.members(path)) and session.node(f"{path}/real").shape[:1] == (frames,):
            paired = np.asarray(session.read(f"{path}/paired"), dtype=float)
            return np.asarray(session.read(f"{path}/real"), dtype=float), paired if paired.ndim == 4 else paired[:, :, None, :]
    return None


def compose_image(frame: np.ndarray, markers: np.ndarray, pairs: tuple[np.ndarray, np.ndarray] | None,
                  size: tuple[int, int]) -> Image.Image:
    """The frame scaled to fit ``size`` (width, height) px with its aspect ratio (a half-block cell
    is two square pixels), grey, with markers and pair lines drawn."""
    grey = np.asarray(frame, dtype=float)
    lo, hi = float(np.nanmin(grey)), float(np.nanmax(grey))
    scaled = np.zeros_like(grey) if hi <= lo else (grey - lo) * (255.0 / (hi - lo))
    image = Image.fromarray(np.nan_to_num(scaled).astype(np.uint8)).convert("RGB")
    scale = min(size[0] / frame.shape[1], size[1] / frame.shape[0])
    size = (max(1, round(frame.shape[1] * scale)), max(1, round(frame.shape[0] * scale)))
    sx, sy = size[0] / frame.shape[1], size[1] / frame.shape[0]
    image = image.resize(size, Image.Resampling.BOX)  # area average: a small bright disc stays visible
    draw = ImageDraw.Draw(image)
    if pairs is not None:
        real, paired = pairs
        for r, p in zip(real, paired):
            for q in p:
                if np.isfinite(r).all() and np.isfinite(q).all():
                    draw.line([(r[0] * sx, r[1] * sy), (q[0] * sx, q[1] * sy)], fill=PAIR)
    for x, y in markers:  # a cross 3 px wide: one terminal cell is only 1 x 2 of these pixels
        cx, cy = x * sx, y * sy
        draw.line([(cx - 1, cy), (cx + 1, cy)], fill=MARKER)
        draw.line([(cx, cy - 1), (cx, cy + 1)], fill=MARKER)
    return image


class CameraScreen(Screen[None]):
    """``c`` on the dashboard: the newest frame with markers; tab switches cameras, esc goes back."""

    BINDINGS = [Binding("tab", "next_camera", "Next camera", priority=True),
                Binding("left", "step(-1)", "Frame -1", show=False), Binding("right", "step(1)", "Frame +1", show=False),
                Binding("home", "step(-1e12)", "First", show=False), Binding("end", "step(1e12)", "Last", show=False),
                Binding("escape", "back", "Back")]
    DEFAULT_CSS = """
    CameraScreen #status { height: 1; padding: 0 1; background: $boost; }
    CameraScreen #frame { height: 1fr; content-align: center middle; }
    """

    app: MirrorlabApp

    def __init__(self) -> None:
        super().__init__()
        self.cameras: list[str] = []  # live image streams, "label/stream"
        self.recorded: list[str] | None = None  # recorded image datasets (None: not read yet)
        self.camera = 0  # which camera of either list
        self.index = -1  # recorded: the frame shown (-1: the last)
        self.frames = 0
        self._busy = False
        self._drawn: tuple[int, int, tuple[int, int]] | None = None  # the recorded frame on screen

    @staticmethod
    def unavailable(model: Console) -> str:
        if model.live and not any(len(s.spec.shape) == 2 for s in model.streams.values()):
            return "No instrument of this session streams images; open a recipe with a camera."
        return ""

    def compose(self) -> ComposeResult:
        yield Header()
        yield Static("reading…", id="status", markup=False)
        yield Static(id="frame")
        yield KeysFooter()

    def on_mount(self) -> None:
        self.sub_title = "camera"
        model = self.app.model
        self.cameras = [f"{src}/{name}" for (src, name), s in model.streams.items() if len(s.spec.shape) == 2]
        if model.live:
            self.set_interval(1 / FRAME_HZ, self.refresh_frame)
        self.refresh_frame()

    @property
    def live_view(self) -> bool:
        """Whether live frames are shown (while a camera acquires) rather than recorded ones."""
        instruments = self.app.model.session.instruments
        return any(instruments[c.split("/", 1)[0]].state == "acquiring" for c in self.cameras)

    def _found(self, nodes: object) -> None:
        self.recorded = [n.path for n in nodes if n.path.startswith("/instruments/")  # type: ignore[attr-defined]
                         and n.path.endswith("/data") and len(n.shape) == 3 and n.shape[0] > 0]
        self.refresh_frame()

    def _status(self, text: str) -> None:
        self.query_one("#status", Static).update(Text(text, overflow="ellipsis", no_wrap=True))

    def _frame_size(self) -> tuple[int, int]:
        region = self.query_one("#frame", Static).size
        return max(8, region.width), max(4, 2 * region.height)

    def refresh_frame(self) -> None:
        """Take the frame to show and draw it with its markers in a worker (one at a time): the
        newest live frame while acquiring, else a recorded frame (drawn again only when it changes)."""
        if self._busy:
            return
        model, size = self.app.model, self._frame_size()
        if self.live_view:
            camera = self.cameras[self.camera % len(self.cameras)]
            live = model.streams[tuple(camera.split("/", 1))]  # type: ignore[index]
            if live.latest is None:
                self._status(f"{camera}: no frame yet")
                return
            frame, where = live.latest, f"{camera} at {live.latest_time:.2f} s"
            self._drawn = None
            self._in_worker("draw the camera frame", lambda: self._draw(frame, None, where, size))
        elif self.recorded is None:  # read once which recorded image streams the file holds
            self.recorded = []
            self.app.in_worker("read the session file", lambda: browse.datasets(model.session), self._found,
                               owner=self)
        elif not self.recorded:
            self._status("No image recorded yet: press p (preview) or r (record) on the dashboard."
                         if model.live else "No recorded image stream in this file (a camera's frames/data).")
        elif self._drawn != (self.camera, self.index, size):
            self._drawn = (self.camera, self.index, size)
            camera, index = self.recorded[self.camera % len(self.recorded)], self.index
            self._in_worker("read the camera frame", lambda: self._read(camera, index, size))

    def _in_worker(self, what: str, fn: Any) -> None:
        """Draw one frame in a worker; the next waits until this one is done (or failed)."""
        def job() -> object:
            try:
                return fn()
            finally:
                self._busy = False
        self._busy = True
        self.app.in_worker(what, job, self._shown, owner=self)

    def _read(self, path: str, index: int, size: tuple[int, int]) -> tuple[Pixels, str]:
        session = self.app.model.session
        self.frames = session.node(path).shape[0]
        index = self.frames - 1 if index < 0 else min(index, self.frames - 1)
        pairs = stored_pairs(session, self.frames)
        frame_pairs = None if pairs is None else (pairs[0][index], pairs[1][index])
        name = path.removeprefix("/instruments/").removesuffix("/data")
        return self._draw(session.read(path, index), frame_pairs, f"{name} frame {index + 1}/{self.frames} (← →)", size)

    def _draw(self, frame: np.ndarray, pairs: Any, where: str, size: tuple[int, int]) -> tuple[Pixels, str]:
        cls = detector(self.app.model.session.registry)
        markers = detect(cls, frame) if cls is not None else np.empty((0, 2))
        image = compose_image(frame, markers, pairs, size)
        found = f"{len(markers)} markers ({cls.name})" if cls is not None else "no marker detector installed"
        mirror = f" · {int(np.isfinite(pairs[1]).all(axis=-1).sum())} mirror pairs" if pairs is not None else \
            " · mirror pairs: run the pairing analysis (a)"
        return Pixels.from_image(image), f"{where} · {found}{mirror}"

    def _shown(self, outcome: object) -> None:
        pixels, status = cast("tuple[Pixels, str]", outcome)  # what _draw returns
        self.query_one("#frame", Static).update(pixels)
        self._status(status)

    def action_next_camera(self) -> None:
        self.camera += 1
        self.index = -1
        self.refresh_frame()

    def action_step(self, frames: float) -> None:
        if not self.live_view and self.frames:
            current = self.frames - 1 if self.index < 0 else self.index
            self.index = int(min(max(current + frames, 0), self.frames - 1))
            self.refresh_frame()

    def action_back(self) -> None:
        self.app.pop_screen()
