"""Fails at import, like a plugin whose dependency is not installed."""

import mirrorlab_nonexistent_dependency  # noqa: F401
