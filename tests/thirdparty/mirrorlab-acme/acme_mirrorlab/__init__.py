"""ACME thermometer: a complete, minimal third-party mirrorlab plugin (see docs/writing-plugins.md)."""

from .algorithm import DriftRate
from .controller import AcmeAlarm
from .driver import AcmeThermometer
from .model import AcmeThermometerModel

__all__ = ["AcmeAlarm", "AcmeThermometer", "AcmeThermometerModel", "DriftRate"]
