"""A serial instrument that needs a port but ships no simulator."""

from mirrorlab.core import hookimpl
from mirrorlab.core.devices import SerialInstrument


class Unsimulated(SerialInstrument):
    name = "unsimulated"
    version = "0.0.1"
    description = "a serial device without a simulator"

    @classmethod
    def needs_port(cls, settings):
        return True

    def streams(self):
        return []

    def acquire(self, emit, stop):
        stop.wait()


@hookimpl
def mirrorlab_register_instruments():
    return [Unsimulated]
