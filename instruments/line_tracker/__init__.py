"""The optical line-sensor direction detector of ``instruments.md`` §3 (``OLDT``).

:mod:`.sensor` (pixel geometry, projection, video signal, runs, adaptive threshold),
:mod:`.view` (what a detector sees of a tracking world) and :mod:`.detector` (the OLDT command set
of one detector). The mirror gimbal embeds one detector per axis.
"""
