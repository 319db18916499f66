"""The operator console (``mirrorlab tui``): a Textual app over the live session's public API.

:mod:`.model` (the session as the console sees it, no widgets), :mod:`.app` (the dashboard, its
actions, the screens it opens), :mod:`.screens` (how a screen is declared, :class:`ScreenEntry`,
and the core's own), :mod:`.detail` (one instrument or controller), :mod:`.steps` (the recipe
runner), :mod:`.analysis` (algorithm runs), :mod:`.browser` (the file's tree), :mod:`.plots`,
:mod:`.camera`, :mod:`.browse` (reading the file for them), :mod:`.forms` (forms generated from
parameters), :mod:`.dialogs` (help, errors, device faults), :mod:`.widgets`, :mod:`.latest`.

What a plugin's screens use from here (both light: no Textual is imported with them):
:class:`ScreenEntry`, to declare a screen in ``mirrorlab_register_screens``, and
:class:`LatestOnly`, to compute the newest input off the event loop.
"""

from .latest import LatestOnly
from .screens import ScreenEntry

__all__ = ["LatestOnly", "ScreenEntry"]
