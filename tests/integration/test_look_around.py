"""denied.look_around: one revolution at the yaw-rate limit, hovering, before the first departure (slow: a flight)."""

from __future__ import annotations

import numpy as np
import pytest

import mpcde

pytestmark = pytest.mark.slow


def test_the_drones_turn_once_in_place_then_fly():
    cfg = mpcde.load_scenario("crossing", mode="denied", duration_s=6.0)
    from dataclasses import replace

    cfg = replace(cfg, denied=replace(cfg.denied, look_around=True))
    r = mpcde.fly(cfg)
    a = r.log.arrays
    t, yaw, pos = a["time_s"], np.unwrap(a["yaw"], axis=0), a["pos_world"]
    turn_s = 2 * np.pi / cfg.denied.yaw_rate_max_radps
    during = t <= turn_s - 0.2
    assert np.all(np.linalg.norm(pos[during] - pos[0], axis=-1) < 0.1)  # hovering
    k = np.searchsorted(t, turn_s)
    assert np.all(yaw[k] - yaw[0] > 2 * np.pi - 0.5)  # one revolution, lagging the reference a little
    assert np.all(np.linalg.norm(pos[-1] - pos[0], axis=-1) > 1.0)  # then on its way
