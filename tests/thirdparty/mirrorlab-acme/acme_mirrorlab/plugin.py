"""The entry point module: what this package registers with mirrorlab."""

from mirrorlab.core import hookimpl

from .algorithm import DriftRate
from .controller import AcmeAlarm
from .driver import AcmeThermometer


@hookimpl
def mirrorlab_register_instruments():
    return [AcmeThermometer]


@hookimpl
def mirrorlab_register_algorithms():
    return [DriftRate]


@hookimpl
def mirrorlab_register_controllers():
    return [AcmeAlarm]
