"""Registers an algorithm under a name the ACME plugin already uses."""

from mirrorlab.core import Algorithm, hookimpl


class Clash(Algorithm):
    name = "acme_drift_rate"
    version = "0.0.1"
    description = "a second provider of an existing name"

    def run(self, inputs, params, context):
        return {}


@hookimpl
def mirrorlab_register_algorithms():
    return [Clash]
