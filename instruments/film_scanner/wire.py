"""The FSCAN's binary lines (``instruments.md`` §1.5): 512 pixels, 128 hex digits per line.

The codec is the core's :mod:`mirrorlab.core.devices.wire` (shared with the line-sensor detectors).
"""

#: Pixels of the FSCAN's line sensor: the bits of one binary line.
PIXELS = 512
