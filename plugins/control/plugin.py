"""Registers the built-in controllers."""

from .controllers import Follow

CONTROLLERS = [Follow]
