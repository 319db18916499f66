"""Typed errors of real/mirror pairing."""

from __future__ import annotations

from mirrorlab.core import AlgorithmError


class PairingError(AlgorithmError):
    """Base class of pairing errors."""


class InvalidPairingInput(PairingError, ValueError):
    """Points, epipoles or options have the wrong shape or value."""
