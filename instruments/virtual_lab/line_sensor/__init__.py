"""The optical line-sensor direction detector (``instruments.md`` §3), shared by the simulators
built on it: the line tracker (one detector) and the mirror gimbal (one per axis).

Pure functions: :mod:`.sensor` (pixel geometry, summing projection, video signal, runs, adaptive
threshold) and :mod:`.view` (what a detector sees of a tracking world, the optical faults);
:mod:`.detector` is the OLDT command set of one detector (its ``CLK`` and ``THR`` arguments are the
film scanner's too) and :mod:`.scanned_lines` the scans (signal, period, scheduling) and fault
checks of a simulator built on detectors. The drivers use the sensor's
geometry (:mod:`.sensor`) to turn pixels into angles.
"""
