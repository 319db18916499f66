"""Shared fixtures of the kinematics tests."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def data_dir(shared_data: Path) -> Path:
    """The shared validation data folder (``../shared/data``; the test is skipped without it)."""
    return shared_data
