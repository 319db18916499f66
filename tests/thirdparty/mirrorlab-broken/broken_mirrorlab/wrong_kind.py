"""Returns an algorithm from the instrument registration hook."""

from mirrorlab.core import Algorithm, hookimpl


class NotAnInstrument(Algorithm):
    name = "not_an_instrument"
    version = "0.0.1"
    description = "an algorithm registered as an instrument"

    def run(self, inputs, params, context):
        return {}


@hookimpl
def mirrorlab_register_instruments():
    return [NotAnInstrument]
