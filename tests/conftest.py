"""Shared fixtures: fixed seeds, small scenes."""

from __future__ import annotations

import mpcde  # noqa: F401  (its numerics profile is set before numpy loads: mpcde/numerics.py)
import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    """A generator with a fixed seed."""
    return np.random.default_rng(12345)
