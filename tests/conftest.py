"""Shared fixtures: seeded RNG, real-data location, random cameras."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def shared_data(name: str) -> Path:
    """Path of ``../shared/data/<name>``; skip the test with a reason if it is absent."""
    p = SHARED_DATA / name
    if not p.exists():
        pytest.skip(f"real data {p} is absent (../shared/data not beside the checkout)")
    return p


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(0)
