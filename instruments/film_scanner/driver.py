"""``FilmScanner``: the film digitiser instrument plugin (spec ``instruments.md`` §1).

With ``source = "fscan"`` it drives an FSCAN device (or its simulator) over the line protocol:
homing, heading, and scanning ``lines`` lines per frame. With ``folder``, ``video``, ``camera`` or ``virtual``
(rendered frames of a virtual-lab ``scene``) it reads frames from a
:mod:`~mirrorlab.instruments.film_scanner.sources` object instead and
emits them in the same format, paced at ``frame_rate``. API units: mm and s; the wire speaks
steps, lines, ms, Hz and DAC counts.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from mirrorlab.core import (
    ConfigurationError,
    DeviceDisconnected,
    DeviceReplyError,
    Parameter,
    ParameterSet,
    ProtocolError,
    StreamSpec,
)
from mirrorlab.core.devices import Emit, Identity, Reporter, SerialInstrument, SimulatedWorld, Status
from mirrorlab.core.devices.wire import parse_data_line
from mirrorlab.instruments.virtual_lab import SCENE_NAMES

from .film import PIXEL_MM, Film
from .mechanics import CENTRE_STEPS, HOME_SEARCH_STEPS, STEP_S, STEP_UM, STEPS_PER_LINE
from .model import HEAD_LIMIT_LINES, MAX_LINES, FilmScannerModel
from .sources import CameraSource, FolderSource, FrameSource, VideoSource, load_images, to_scan_frame
from .wire import PIXELS

SCAN_CHUNK = 43                  # lines per SCAN command: 344 = 8 x 43, stop is checked between
FEED_S_PER_LINE = STEPS_PER_LINE * STEP_S
HEAD_ESTIMATE_S = 8.0            # typical heading + recentring time, for the nominal frame rate

Frame = tuple[float, int, np.ndarray]


class FilmScanner(SerialInstrument):
    """Line-scan film digitiser (FSCAN) or a folder / video / camera / virtual-lab stand-in.

    Streams: ``frames`` (uint8 ``(lines, 512)``, 0/255 when binarised) and ``frame_index`` (int64).
    """

    name = "film_scanner"
    version = "1.0.0"
    description = "Line-scan film digitiser (512-px sensor, 344 lines/frame) or folder/video/camera frames"
    kind = "FSCAN"
    simulator = FilmScannerModel
    parameters = ParameterSet(
        Parameter("source", str, "fscan", choices=("fscan", "folder", "video", "camera", "virtual"),
                  help="fscan = serial scanner (or simulator); folder/video/camera/virtual = frame source"),
        Parameter("path", str, "", path=True, help="folder of PNG/TIFF/JPEG frames or video file; for fscan "
                                        "simulation the film's frame images (empty = generated film)"),
        Parameter("camera_index", int, 0, bounds=(0, 63), help="OpenCV camera index (source = camera)"),
        Parameter("threshold", int, 128, bounds=(0, 255), help="comparator DAC level, counts"),
        Parameter("clock_hz", float, 73_000.0, unit="Hz", bounds=(1_000.0, 307_692.0),
                  help="sensor clock; exposure = 512 / clock (the 6502 host limits it to 307.7 kHz)"),
        Parameter("lines", int, MAX_LINES, bounds=(1, MAX_LINES), help="lines scanned per frame"),
        Parameter("head_sl1", int, 128, bounds=(0, 255), help="heading threshold for the clear band"),
        Parameter("head_sl2", int, 128, bounds=(0, 255), help="heading threshold for the dark frame edge"),
        Parameter("head_skip", int, 37, bounds=(0, 384), help="lines skipped into the frame after heading"),
        Parameter("frame_rate", float, 10.0, unit="Hz", bounds=(0.01, 1000.0),
                  help="shooting rate of folder/video/virtual frames (paced at it, stamped k / rate from "
                       "the first; a camera's frames are stamped on arrival) and of a virtual-lab film"),
        Parameter("loop", bool, False, help="restart a folder or video at its end"),
        Parameter("binarise", bool, True, help="binarise folder/video/camera frames at `threshold`"),
        Parameter("scene", str, "", choices=("", *SCENE_NAMES),
                  help="virtual-lab scene: the frames of source = virtual, and the film of a simulated "
                       "fscan (shot at `frame_rate`); empty = none"),
        Parameter("scene_frames", int, 34, bounds=(1, 100_000),
                  help="frames of the simulated film (the generated marker film, or the virtual-lab scene's), "
                       "or frames before the virtual source ends"),
    )

    def __init__(self, label: str, port: str | None = None, settings: Mapping[str, Any] | None = None,
                 timeout: float = 2.0, report: Reporter | None = None) -> None:
        super().__init__(label, port, settings, timeout, report)
        self._source: FrameSource | None = None
        self._homed = False
        # Index of the next frame: a reconnect (or a new start) resumes there instead of at frame 0.
        self._next_frame = 0

    @classmethod
    def needs_port(cls, settings: Mapping[str, Any]) -> bool:
        """Only the line-scan digitiser is on a serial port; folders, videos and cameras are not."""
        return settings.get("source", "fscan") == "fscan"

    @classmethod
    def make_simulator(cls, settings: Mapping[str, Any], seed: int,
                       world: SimulatedWorld | None = None) -> FilmScannerModel:
        """A simulator for these settings: the film is made of ``path``'s images if given, else generated
        (its own scene: the scanner takes no part in a shared ``world``)."""
        values = cls.parameters.validate(dict(settings))
        if values["path"]:
            film = Film.from_images(load_images(values["path"]))
        elif values["scene"]:
            from .virtual import virtual_film  # renders with OpenCV: imported when used
            film = virtual_film(values["scene"], values["frame_rate"], values["scene_frames"])
        else:
            film = Film.generated(n_frames=values["scene_frames"])
        return FilmScannerModel(film, seed=seed)

    @property
    def is_serial(self) -> bool:
        return self.settings["source"] == "fscan"

    # -- lifecycle -----------------------------------------------------------------------------------
    def connect(self) -> None:
        if self.is_serial:
            super().connect()
        elif self._source is None:
            self._source = open_source(self.settings["source"], self.settings["path"],
                                       self.settings["camera_index"], scene=self.settings["scene"],
                                       frame_rate=self.settings["frame_rate"],
                                       n_frames=self.settings["scene_frames"])
            if self._next_frame:
                self._source.seek(self._next_frame)

    def identify(self) -> Identity:
        if self.is_serial:
            return super().identify()
        self.identity = self._require_source().identity()
        return self.identity

    def apply_settings(self, settings: dict[str, Any]) -> None:
        if not self.is_serial or self.client is None:
            return  # frame sources use the settings locally; nothing to send
        self.query(f"CLK {int(round(settings['clock_hz']))}")
        self.query(f"THR {settings['threshold']}")
        self.query(f"HEADTHR {settings['head_sl1']} {settings['head_sl2']} {settings['head_skip']}")

    def streams(self) -> list[StreamSpec]:
        lines = self.settings["lines"]
        if self.is_serial:
            rate = 1.0 / (lines * self.line_seconds + HEAD_ESTIMATE_S)
        else:
            rate = self.settings["frame_rate"]
        return [
            StreamSpec("frames", "u1", (lines, PIXELS), "", rate,
                       f"film frames, {lines} lines x {PIXELS} px at {PIXEL_MM * 1000:.3f} µm, 0/255"),
            StreamSpec("frame_index", "i8", (), "", rate, "index of the film frame (or file/video frame)"),
        ]

    def status(self) -> Status:
        if self.is_serial:
            return super().status()
        source = self._source
        return Status("IDLE" if source is None else "READY", (), source is not None,
                      {"kind": source.kind if source else self.settings["source"]})

    def close(self) -> None:
        super().close()
        self._homed = False
        if self._source is not None:
            self._source.close()
            self._source = None

    # -- acquisition -----------------------------------------------------------------------------------
    def acquire(self, emit: Emit, stop: threading.Event) -> None:
        now: Callable[[], float] = getattr(emit, "now", time.monotonic)
        frames = self._scan_frames(stop, now) if self.is_serial else self._source_frames(stop, now)
        for t, index, frame in frames:
            emit("frames", np.array([t]), frame[None])
            emit("frame_index", np.array([t]), np.array([index], dtype=np.int64))

    def read(self) -> dict[str, np.ndarray]:
        """Scan (or read) one frame: ``{"frames": (1, lines, 512), "frame_index": (1,)}``."""
        stop = threading.Event()
        frames = self._scan_frames(stop, time.monotonic) if self.is_serial else self._source_frames(
            stop, time.monotonic, pace=False, wrap=True)
        for _, index, frame in frames:
            return {"frames": frame[None], "frame_index": np.array([index], dtype=np.int64)}
        raise DeviceDisconnected(f"{self.device_name}: no frame to read (end of film or source); "
                                 "check the film is loaded or the source has frames")

    def _scan_frames(self, stop: threading.Event, now: Callable[[], float]) -> Iterator[Frame]:
        if not self._homed:
            self.prepare()
        while not stop.is_set():
            try:
                self.head()
            except DeviceReplyError as exc:
                if exc.code != "E11":
                    raise
                self.report("info", "end_of_film", f"{self.device_name}: no further frame ({exc.text})")
                return
            t = now()
            frame = self.scan(self.settings["lines"], stop)[0]
            if frame.shape[0] < self.settings["lines"]:
                return  # stopped inside a frame: a partial frame is not emitted
            index, self._next_frame = self._next_frame, self._next_frame + 1
            yield t, index, frame

    def _source_frames(self, stop: threading.Event, now: Callable[[], float], pace: bool = True,
                       wrap: bool | None = None) -> Iterator[Frame]:
        source = self._require_source()
        wrap = self.settings["loop"] if wrap is None else wrap
        period = 1.0 / self.settings["frame_rate"]
        due = time.monotonic()
        anchor: tuple[float, int] | None = None  # (stamp, index) of the frame shooting times count from
        while not stop.is_set():
            item = source.read()
            if item is None and wrap:
                source.rewind()
                item = source.read()
            if item is None:
                return
            index, img = item
            t = now()
            if not source.live:  # frame k was shot at k / frame_rate: a slow read must not skew the stamps
                if anchor is None or index < self._next_frame:  # first frame, or rewound
                    anchor = (t, index)
                t = anchor[0] + (index - anchor[1]) * period
            self._next_frame = index + 1
            yield t, index, to_scan_frame(img, self.settings["lines"], self.settings["threshold"],
                                          self.settings["binarise"])
            if pace:
                due += period
                stop.wait(max(0.0, due - time.monotonic()))

    def _require_source(self) -> FrameSource:
        if self._source is None:
            raise DeviceDisconnected(f"{self.device_name} is not connected; call connect() first")
        return self._source

    # -- FSCAN operations (API units: mm, s) ---------------------------------------------------------
    @property
    def line_seconds(self) -> float:
        """Modelled time per scanned line: sensor read (512 / clock) plus the 10-step feed, s."""
        return 512.0 / self.settings["clock_hz"] + FEED_S_PER_LINE

    def _long_timeout(self, seconds: float) -> float:
        # Real-time devices take the modelled time; allow 50 % plus the normal reply timeout.
        return self.timeout + 1.5 * seconds

    def prepare(self) -> float:
        """Clamp the film to the base, home the carrier, clamp the film to it; returns seconds."""
        self.clamp("BASE")
        seconds = self.home()
        self.clamp("CARRIER")
        return seconds

    def home(self) -> float:
        """``HOME`` (LCHOME + CHOME); returns the device's time for it, s."""
        reply = self.query("HOME", self._long_timeout((HOME_SEARCH_STEPS + CENTRE_STEPS) * STEP_S))
        self._homed = True
        return reply.field(0, "ms", float) / 1000.0

    def clamp(self, where: str) -> None:
        """Close the solenoid clamp ``"BASE"`` or ``"CARRIER"``."""
        self.query(f"CLAMP {where.upper()}")

    def head(self) -> tuple[int, float]:
        """Find the next frame (``HEAD``); returns (lines advanced, seconds)."""
        worst = HEAD_LIMIT_LINES * self.line_seconds + 3 * CENTRE_STEPS * STEP_S
        reply = self.query("HEAD", self._long_timeout(worst))
        return reply.field(0, "lines", int), reply.field(1, "ms", float) / 1000.0

    def scan(self, lines: int, stop: threading.Event | None = None) -> tuple[np.ndarray, float]:
        """Scan ``lines`` lines (feeding one line after each); returns (0/255 image, seconds).

        The scan is sent in chunks of :data:`SCAN_CHUNK` lines; when ``stop`` is set between chunks
        the lines read so far are returned.
        """
        rows: list[np.ndarray] = []
        seconds = 0.0
        while len(rows) < lines and not (stop is not None and stop.is_set()):
            n = min(SCAN_CHUNK, lines - len(rows))
            reply = self.query(f"SCAN {n}", self._long_timeout(n * self.line_seconds))
            if len(reply.data) != n:
                raise ProtocolError(f"{self.device_name}: SCAN {n} returned {len(reply.data)} lines")
            for j, line in enumerate(reply.data):
                index, bits = self._data_line(line, "L")
                if index != j:
                    raise ProtocolError(f"{self.device_name}: SCAN line {index} arrived as line {j}")
                rows.append(bits)
            seconds += reply.field(1, "ms", float) / 1000.0
        image = np.array(rows, dtype=np.uint8).reshape(-1, PIXELS) * np.uint8(255)
        return image, seconds

    def _data_line(self, line: str, tag: str) -> tuple[int, np.ndarray]:
        try:
            return parse_data_line(line, tag, PIXELS)
        except ProtocolError as exc:
            raise ProtocolError(f"{self.device_name}: {exc}; check the cable and the baud rate") from None

    def read_line(self) -> np.ndarray:
        """``LINE?``: the binary line at the current position, uint8 0/255 ``(512,)``."""
        reply = self.query("LINE?")
        return self._data_line(_one(reply.data, "LINE?"), "LINE")[1] * np.uint8(255)

    def grey_profile(self) -> np.ndarray:
        """``GREY?``: grey levels of the current line by threshold sweep, uint8 ``(512,)``."""
        reply = self.query("GREY?", self._long_timeout(256 * 512.0 / self.settings["clock_hz"]))
        parts = _one(reply.data, "GREY?").split(" ")
        if parts[0] != "GREY" or len(parts) != PIXELS + 2:
            raise ProtocolError(f"{self.device_name}: malformed GREY line ({len(parts)} fields)")
        try:
            return np.array(parts[2:], dtype=np.int64).clip(0, 255).astype(np.uint8)
        except ValueError:
            raise ProtocolError(f"{self.device_name}: GREY line holds a value that is not an integer") from None

    def feed(self, mm: float) -> float:
        """Move the carrier by ``mm`` (rounded to whole lines); returns the carrier position, mm."""
        lines = int(round(mm / PIXEL_MM))
        reply = self.query(f"FEED {lines}", self._long_timeout(abs(lines) * FEED_S_PER_LINE))
        return reply.field(0, "pointer", int) * STEP_UM / 1000.0

    def position(self) -> tuple[float, float]:
        """``POS?``: (carrier position from the left limit switch, film advance), both mm."""
        reply = self.query("POS?")
        return (reply.field(0, "pointer", int) * STEP_UM / 1000.0,
                reply.field(1, "film steps", int) * STEP_UM / 1000.0)


def _one(data: list[str], command: str) -> str:
    if len(data) != 1:
        raise ProtocolError(f"{command} returned {len(data)} data lines, expected 1; check the cable and "
                            "that the port is the scanner's")
    return data[0]


def open_source(source: str, path: str, camera_index: int, *, scene: str = "", frame_rate: float = 10.0,
                n_frames: int = 0) -> FrameSource:
    """Create and open the frame source named by the ``source`` setting.

    ``virtual`` renders frames of the virtual-lab ``scene`` (frame k at t = k / ``frame_rate``,
    ``n_frames`` frames, 0 = endless).
    """
    if source in ("folder", "video") and not path:
        raise ConfigurationError(f"source '{source}' needs the `path` setting (a "
                                 f"{'folder of images' if source == 'folder' else 'video file'})")
    frame_source: FrameSource
    if source == "folder":
        frame_source = FolderSource(Path(path))
    elif source == "video":
        frame_source = VideoSource(Path(path))
    elif source == "camera":
        frame_source = CameraSource(camera_index)
    elif source == "virtual":
        if not scene:
            raise ConfigurationError(f"source 'virtual' needs the `scene` setting ({', '.join(SCENE_NAMES)})")
        from .virtual import VirtualSource  # renders with OpenCV: imported when used
        frame_source = VirtualSource(scene, frame_rate, n_frames)
    else:
        raise ValueError(f"unknown frame source {source!r}")
    frame_source.open()
    return frame_source
