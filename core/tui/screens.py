"""The screens the console's dashboard opens: how one is declared, and the core's own.

A screen is declared by a :class:`ScreenEntry` (a key, a title and a help line for the command
palette and the help, and where its class lives), so that declaring it imports nothing: the class
is imported when the operator first opens it. Plugins register theirs through the hook
``mirrorlab_register_screens`` (:mod:`mirrorlab.core.hookspecs`); :data:`SCREENS` are the core's.
This module imports no Textual, so a plugin module that registers screens stays light.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import import_module
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from textual.screen import Screen


@dataclass(frozen=True)
class ScreenEntry:
    """A screen the dashboard opens by its key and from the command palette (ctrl+p).

    Parameters
    ----------
    name
        Identifier, unique among every plugin's screens (prefix yours: ``acme_trend``); what the
        plugin declares as ``screen.<name>`` in the entry-point group ``mirrorlab.provides``.
    key
        The dashboard key that opens it, as Textual names keys (``"v"``, ``"f5"``, ``"ctrl+t"``).
        A key the dashboard or an earlier screen already uses is not bound (the screen still opens
        from the palette) and the console says so.
    title
        The palette command and the footer label (``"Virtual chain"``).
    help
        One line: what the screen shows and does, for the palette and the help (``?``).
    target
        ``"module:Class"`` of the :class:`textual.screen.Screen` subclass, imported when the screen
        is first opened (a module starting with ``.`` is relative to ``mirrorlab.core.tui``). The
        class is built without arguments and reaches the session as ``self.app.model`` (a
        :class:`~mirrorlab.core.tui.model.Console`); it may define a static
        ``unavailable(model) -> str``, why it cannot open now (``""``: it can), which the console
        shows instead of opening it.
    """

    name: str
    key: str
    title: str
    help: str
    target: str

    def __post_init__(self) -> None:
        empty = [field for field in ("name", "key", "title", "help") if not getattr(self, field).strip()]
        if empty:
            raise ValueError(f"screen {self.name!r}: {', '.join(empty)} must not be empty")
        module, _, cls = self.target.partition(":")
        if not module or not cls:
            raise ValueError(f"screen {self.name!r}: target {self.target!r} is not \"module:Class\"")

    def load(self) -> type[Screen]:
        """The screen class (imports its module)."""
        module, _, name = self.target.partition(":")
        return getattr(import_module(module, __package__), name)


#: The core's own screens, in the order of their keys in the footer, the palette and the help;
#: plugins add theirs after these (``mirrorlab_register_screens``).
SCREENS: list[ScreenEntry] = [
    ScreenEntry("steps", "t", "Steps", "the recipe's steps: run from one, see progress, cancel", ".steps:StepsScreen"),
    ScreenEntry("analysis", "a", "Analysis", "run an algorithm: its form, progress, cancel, result",
                ".analysis:AnalysisScreen"),
    ScreenEntry("browse", "b", "Browse", "the session file: tree, previews, attributes, provenance",
                ".browser:BrowserScreen"),
    ScreenEntry("plots", "g", "Plots", "trajectories, velocities, joint angles, tracker angles", ".plots:PlotsScreen"),
    ScreenEntry("camera", "c", "Camera", "the newest frame, detected markers, mirror pairs", ".camera:CameraScreen"),
]
