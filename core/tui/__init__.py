"""The operator console (``mirrorlab tui``): a Textual app over the live session's public API.

:mod:`.model` (the session as the console sees it, no widgets), :mod:`.app` (the dashboard and
its actions), :mod:`.detail` (one instrument or controller), :mod:`.forms` (forms generated from
parameters), :mod:`.dialogs` (help, errors, device faults).
"""
