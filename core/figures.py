"""What every module that writes PNG figures shares: where they go by default, and how one is saved.

Plugins and instruments draw their figures on a matplotlib ``Figure`` (no pyplot state) and save
it with :func:`save_figure`; a recipe step's ``figures`` folder defaults to :func:`figures_folder`.
matplotlib is imported only when a figure is saved, so importing this module (a step that names
its default folder) costs nothing at start-up.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["figures_folder", "save_figure"]


def figures_folder(session: Any, given: str | os.PathLike[str] = "") -> Path:
    """``given``, or else the folder ``<session stem>-figures`` beside the session file.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> s = SimpleNamespace(path=Path("runs/demo.h5"))
    >>> figures_folder(s).as_posix(), figures_folder(s, "out").as_posix()
    ('runs/demo-figures', 'out')
    """
    return Path(given) if given else session.path.with_name(session.path.stem + "-figures")


def save_figure(fig: Figure, path: str | os.PathLike[str], dpi: float = 100) -> Path:
    """Write ``fig`` as a PNG file at ``path`` (parent folders are created) with the Agg canvas; return the path.

    ``dpi`` is dots per inch: the image is ``fig.get_size_inches() * dpi`` pixels.

    Examples
    --------
    >>> import tempfile
    >>> from matplotlib.figure import Figure
    >>> fig = Figure(figsize=(2, 1))
    >>> _ = fig.add_subplot().plot([0, 1], [1, 0])
    >>> p = save_figure(fig, Path(tempfile.mkdtemp()) / "new" / "f.png", dpi=50)
    >>> p.name, p.read_bytes()[16:24] == (100).to_bytes(4, "big") + (50).to_bytes(4, "big")   # PNG width, height
    ('f.png', True)
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg  # here: matplotlib only once a figure is saved

    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    FigureCanvasAgg(fig)
    fig.savefig(out, dpi=dpi)
    return out
