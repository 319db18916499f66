"""The operator console (``mirrorlab tui``): a Textual app over the live session's public API.

:mod:`.model` (the session as the console sees it, no widgets), :mod:`.app` (the dashboard, its
actions and ``SCREENS``, the screens it opens), :mod:`.detail` (one instrument or controller),
:mod:`.steps` (the recipe runner), :mod:`.analysis` (algorithm runs), :mod:`.browser` (the file's
tree), :mod:`.plots`, :mod:`.camera`, :mod:`.browse` (reading the file for them), :mod:`.forms`
(forms generated from parameters), :mod:`.dialogs` (help, errors, device faults), :mod:`.widgets`.
"""
