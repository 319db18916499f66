"""Frame sources that stand in for the scanner hardware: an image folder, a video file, a camera.

Each source yields greyscale frames; :func:`to_scan_frame` turns any of them into the scanner's
frame format (``lines x 512`` uint8, binarised like the comparator unless asked not to), so that
everything downstream sees the same stream whatever the source.
"""

from __future__ import annotations

import re
from abc import ABC, abstractmethod
from pathlib import Path

import cv2
import numpy as np
from mirrorlab.core import ConfigurationError, DataError, DeviceDisconnected, DeviceError
from mirrorlab.core.devices import Identity

from .wire import PIXELS

IMAGE_SUFFIXES = (".png", ".tif", ".tiff", ".jpg", ".jpeg", ".bmp")
FRAME_LINES = 384            # a full 24 x 18 mm frame at the 46.875 µm pitch


def natural_key(path: Path) -> list[object]:
    """Sort key that orders ``2.png`` before ``10.png``."""
    return [int(part) if part.isdigit() else part.lower() for part in re.split(r"(\d+)", path.name)]


def image_files(folder: Path) -> list[Path]:
    """Image files of ``folder`` in natural order.

    Raises
    ------
    ConfigurationError
        The folder is missing or holds no PNG/TIFF/JPEG/BMP image.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise ConfigurationError(f"frame folder {str(folder)!r} does not exist; check the `path` setting "
                                 "(it must be a folder of PNG/TIFF/JPEG frames)")
    files = sorted((p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES), key=natural_key)
    if not files:
        raise ConfigurationError(f"frame folder {str(folder)!r} holds no PNG/TIFF/JPEG images; check the "
                                 f"`path` setting and the file suffixes ({', '.join(IMAGE_SUFFIXES)})")
    return files


def read_grey(path: Path) -> np.ndarray:
    """Read one image as 8-bit greyscale.

    Raises
    ------
    DataError
        The file cannot be read or decoded, or it is a JPEG cut short (OpenCV would decode the
        part that is there and fill the rest with grey).
    """
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise DataError(f"cannot read image {str(path)!r} ({exc.strerror}); check that it exists and is "
                        "readable, or remove it from the folder") from None
    # A JPEG's last scan (marker FF DA) ends with the end-of-image marker FF D9; a cut file lacks it.
    if path.suffix.lower() in (".jpg", ".jpeg") and data.rfind(b"\xff\xd9") < data.rfind(b"\xff\xda"):
        raise DataError(f"image {str(path)!r} is cut short (its JPEG data stop before the end marker); "
                        "replace or remove it")
    try:
        img = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE) if data else None
    except cv2.error:  # some damaged headers fail OpenCV's own checks instead of returning None
        img = None
    if img is None:
        raise DataError(f"image {str(path)!r} cannot be decoded (damaged, or not a PNG/TIFF/JPEG/BMP); "
                        "replace or remove it")
    return img


def load_images(path: str | Path, max_frames: int = 1000) -> list[np.ndarray]:
    """All frames of a folder or video file as greyscale arrays (to build a simulated film)."""
    path = Path(path)
    source: FrameSource = FolderSource(path) if path.is_dir() else VideoSource(path)
    source.open()
    try:
        frames = []
        while len(frames) < max_frames and (item := source.read()) is not None:
            frames.append(item[1])
        return frames
    finally:
        source.close()


def to_scan_frame(img: np.ndarray, lines: int, threshold: int, binarise: bool) -> np.ndarray:
    """Resample a greyscale frame to the scanner's geometry.

    The image is taken as a whole 24 x 18 mm frame: resized to 512 x 384 px (aspect not kept), and
    the central ``lines`` rows are returned, binarised to 0/255 at ``threshold`` like the
    comparator when ``binarise`` (else the grey values).
    """
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    shrink = img.shape[0] > FRAME_LINES or img.shape[1] > PIXELS
    frame = cv2.resize(img, (PIXELS, FRAME_LINES), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)
    top = (FRAME_LINES - lines) // 2
    frame = frame[top:top + lines]
    if binarise:
        frame = np.where(frame > threshold, 255, 0).astype(np.uint8)
    return np.ascontiguousarray(frame, dtype=np.uint8)


class FrameSource(ABC):
    """A source of greyscale frames: ``open``, ``read`` until ``None``, ``rewind``, ``close``."""

    kind: str = ""
    #: A live source's frames are stamped when they arrive. The frames of a recording (folder, video,
    #: virtual scene) were shot at ``index / frame_rate``, however long reading them takes.
    live: bool = False

    @abstractmethod
    def open(self) -> None:
        """Open the source; raise :class:`DeviceDisconnected` saying what to check if impossible."""

    @abstractmethod
    def read(self) -> tuple[int, np.ndarray] | None:
        """The next ``(frame index, greyscale image)``, or ``None`` at the end."""

    @abstractmethod
    def rewind(self) -> None:
        """Start again from the first frame."""

    def seek(self, index: int) -> None:
        """Make ``index`` the next frame :meth:`read` returns (used to resume after a reconnect).

        The default reads and discards frames; sources with random access override it.
        """
        self.rewind()
        for _ in range(index):
            if self.read() is None:
                return

    @abstractmethod
    def close(self) -> None:
        """Release the source (idempotent)."""

    @abstractmethod
    def identity(self) -> Identity:
        """What the source is (kind ``FOLDER``, ``VIDEO`` or ``CAMERA``)."""


class FolderSource(FrameSource):
    """Frames from a folder of images in natural order (``2.png`` before ``10.png``)."""

    kind = "FOLDER"

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self.files: list[Path] = []
        self._next = 0

    def open(self) -> None:
        self.files = image_files(self.folder)
        self._next = 0

    def read(self) -> tuple[int, np.ndarray] | None:
        if self._next >= len(self.files):
            return None
        index = self._next
        self._next += 1
        return index, read_grey(self.files[index])

    def rewind(self) -> None:
        self._next = 0

    def seek(self, index: int) -> None:
        self._next = min(index, len(self.files))

    def close(self) -> None:
        self.files = []

    def identity(self) -> Identity:
        return Identity(self.kind, "mirrorlab", "folder", f"{len(self.files)} frames", str(self.folder))


class _CaptureSource(FrameSource):
    """Shared cv2.VideoCapture handling for video files and cameras."""

    def __init__(self) -> None:
        self.capture: cv2.VideoCapture | None = None
        self._index = 0

    @abstractmethod
    def _open_capture(self) -> cv2.VideoCapture:
        ...

    @abstractmethod
    def _cannot_open(self) -> DeviceError:
        """Why the capture did not open: a :class:`ConfigurationError` if no retry can help."""

    def open(self) -> None:
        self.close()
        capture = self._open_capture()
        if not capture.isOpened():
            capture.release()
            raise self._cannot_open()
        self.capture = capture
        self._index = 0

    def read(self) -> tuple[int, np.ndarray] | None:
        if self.capture is None:
            raise DeviceDisconnected(f"{self.kind.lower()} source is not open; connect first")
        ok, img = self.capture.read()
        if not ok or img is None:
            return None
        index = self._index
        self._index += 1
        return index, cv2.cvtColor(img, cv2.COLOR_BGR2GRAY) if img.ndim == 3 else img

    def rewind(self) -> None:
        self.open()

    def close(self) -> None:
        if self.capture is not None:
            self.capture.release()
            self.capture = None


class VideoSource(_CaptureSource):
    """Frames of a video file (any container/codec the OpenCV build can decode)."""

    kind = "VIDEO"

    def __init__(self, path: str | Path) -> None:
        super().__init__()
        self.path = Path(path)

    def _open_capture(self) -> cv2.VideoCapture:
        return cv2.VideoCapture(str(self.path))

    def _cannot_open(self) -> DeviceError:
        if not self.path.exists():
            return ConfigurationError(f"video file {str(self.path)!r} does not exist; check the `path` setting")
        return ConfigurationError(f"cannot decode video {str(self.path)!r}; check that the file is a video OpenCV "
                                  "can read (e.g. MJPG in AVI) or convert it to a folder of PNG frames")

    def identity(self) -> Identity:
        count = int(self.capture.get(cv2.CAP_PROP_FRAME_COUNT)) if self.capture is not None else 0
        return Identity(self.kind, "mirrorlab", "video", f"{count} frames", str(self.path))


class CameraSource(_CaptureSource):
    """Frames of a live camera (``cv2.VideoCapture(index)``)."""

    kind = "CAMERA"
    live = True

    def __init__(self, index: int) -> None:
        super().__init__()
        self.index = int(index)

    def _open_capture(self) -> cv2.VideoCapture:
        return cv2.VideoCapture(self.index)

    def _cannot_open(self) -> DeviceError:  # unplugged, or busy: a reconnect may succeed
        return DeviceDisconnected(f"cannot open camera {self.index}; check that it is plugged in, that "
                                  f"/dev/video{self.index} exists and is readable by you, and that no other "
                                  "program uses it (or set `camera_index`)")

    def rewind(self) -> None:
        """A live camera has no beginning: nothing to do."""

    def identity(self) -> Identity:
        return Identity(self.kind, "mirrorlab", "camera", "opencv", str(self.index))
