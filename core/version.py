"""Installed versions of mirrorlab and its dependencies (light: the CLI's ``--version`` reads it)."""

from __future__ import annotations

from importlib import metadata


def distribution_version(dist: str) -> str:
    """The installed version of distribution ``dist``, or ``""`` if it is not installed."""
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return ""


def mirrorlab_version() -> str:
    """The installed mirrorlab version (``"0+unknown"`` when run from an uninstalled tree)."""
    return distribution_version("mirrorlab") or "0+unknown"
