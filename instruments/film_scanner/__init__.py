"""The film scanner instrument: the line-scan film digitiser of ``instruments.md`` §1.

``FilmScanner`` is the plugin (serial FSCAN device, or a folder / video / camera frame source);
``FilmScannerModel`` is its simulator; ``Film`` is the film strip the simulator scans.
"""

from .driver import FilmScanner
from .film import Film, Marker
from .model import FilmScannerModel

__all__ = ["Film", "FilmScanner", "FilmScannerModel", "Marker"]
