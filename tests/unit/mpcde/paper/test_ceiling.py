"""The all-round bound of `mpcde paper ceiling` (mpcde.paper.ceiling), without flying: what the twin is fed, and the
flights it accepts."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mpcde.errors import ConfigError
from mpcde.flight.observed_area import ObservedArea
from mpcde.paper.ceiling import AllRoundArea, Ceiling, parse_flight
from mpcde.sweep.spec import sweep_from_dict


def _camera_at(x: float, y: float, heading: float) -> np.ndarray:
    """transform_camera_to_world (4, 4) of a level camera at (x, y, 1.5 m) whose optical axis points at ``heading``."""
    T = np.eye(4)
    T[:3, 2] = [math.cos(heading), math.sin(heading), 0.0]  # optical axis (camera z)
    T[:3, 0] = [math.sin(heading), -math.cos(heading), 0.0]  # camera x, right
    T[:3, 1] = np.cross(T[:3, 2], T[:3, 0])
    T[:3, 3] = [x, y, 1.5]
    return T


def test_the_flights_own_area_is_untouched_and_the_twin_sees_the_disc_it_stands_in():
    """The session's metric gets exactly the frames a plain ObservedArea would; the twin, fed the same pose, marks
    (nearly) the whole disc of the depth range, pi r^2, which bounds the 85 deg fan from above."""
    args = ([], (20.0, 20.0), 1, 85.0, 4.0)
    shadow, plain = AllRoundArea(*args), ObservedArea(*args)
    for heading in (0.0, 0.3):
        shadow.add_frame(0, _camera_at(0.0, 0.0, heading))
        plain.add_frame(0, _camera_at(0.0, 0.0, heading))
    assert shadow.areas_m2() == plain.areas_m2()
    own, ceiling = shadow.areas_m2()[1], shadow.all_round.areas_m2()[1]
    assert own < ceiling
    assert ceiling == pytest.approx(math.pi * 4.0**2, rel=0.05)  # cells a ray touches count whole: a few % over


def test_a_line_gives_both_areas_and_the_headroom():
    line = Ceiling(2, 7, "denied.yaw={}", 100.0, 150.0).line()
    assert line == "2  7  denied.yaw={}  100.0  150.0  +50.0 %"


@pytest.mark.parametrize("text", ["0:x", "1", "3:0", "-1:0", "0:-1", "0:4294967296"])
def test_a_flight_that_is_not_cell_colon_seed_of_the_sweep_is_refused_in_one_line(text):
    spec = sweep_from_dict({"base": "crossing", "seeds": 2, "axes": {"planner.cruise_speed_mps": [0.5, 1.0, 2.0]}}, check_cells=False)
    assert parse_flight("2:5", spec) == (2, 5)  # any seed: the flight need not be one the sweep flew
    with pytest.raises(ConfigError, match="^--flights="):
        parse_flight(text, spec)
