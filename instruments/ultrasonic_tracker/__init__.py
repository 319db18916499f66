"""The ultrasonic direction tracker of ``instruments.md`` §2 (``USDF``).

So far only its acoustics (:mod:`.acoustics`: element and array directivity, corrected steering,
echo timing); the driver, simulator and search law are not written yet, so no plugin is registered.
"""
