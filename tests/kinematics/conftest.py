"""Shared fixtures of the kinematics tests (data folder outside the repository)."""

from __future__ import annotations

from pathlib import Path

import pytest

DATA = Path(__file__).resolve().parents[2].parent / "shared" / "data"


@pytest.fixture(scope="session")
def data_dir() -> Path:
    assert DATA.is_dir(), f"shared validation data not found at {DATA}"
    return DATA
