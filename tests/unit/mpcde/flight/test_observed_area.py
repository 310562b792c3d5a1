"""Observed area S_obs: the raster of the camera's level fan against closed-form areas and shadows."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mpcde.flight.observed_area import CELL_M, ObservedArea
from sim.types import ObstacleSpec


def camera(x: float, y: float, z: float, heading: float) -> np.ndarray:
    """A level camera (optical axis = its z) at (x, y, z) looking along ``heading``."""
    T = np.eye(4)
    fwd = np.array([math.cos(heading), math.sin(heading), 0.0])
    left = np.array([-math.sin(heading), math.cos(heading), 0.0])
    T[:3, :3] = np.stack([-left, np.array([0.0, 0.0, -1.0]), fwd], axis=1)  # x right, y down, z forward
    T[:3, 3] = (x, y, z)
    return T


def cell_seen(area: ObservedArea, drone: int, x: float, y: float) -> bool:
    i, j = (np.array([x, y]) - area.origin_xy) // CELL_M
    return bool(area.seen[drone, int(i), int(j)])


SECTOR = math.pi * 10.0**2 * 85.0 / 360.0  # 74.2 m^2
RIM = (2 * 10.0 + 10.0 * math.radians(85.0)) * CELL_M  # the perimeter's cells: what a touched-cell raster may add


def test_open_ground_gives_the_sector_area():
    """The fan's area, plus at most a cell's width along its perimeter (a cell a ray touches counts whole)."""
    area = ObservedArea((), (30.0, 30.0), 1, 85.0, 10.0)
    area.add_frame(0, camera(0.0, 0.0, 1.5, 0.3))
    per, swarm = area.areas_m2()
    assert SECTOR < per[0] < SECTOR + RIM and swarm == per[0]


def test_frames_unite_and_a_repeated_view_adds_nothing():
    area = ObservedArea((), (30.0, 30.0), 2, 85.0, 10.0)
    for _ in range(3):
        area.add_frame(0, camera(0.0, 0.0, 1.5, 0.0))
    area.add_frame(0, camera(0.0, 0.0, 1.5, math.pi))  # the opposite sector
    area.add_frame(1, camera(0.0, 0.0, 1.5, 0.0))  # drone 1 sees drone 0's first sector again
    per, swarm = area.areas_m2()
    assert 2 * SECTOR < per[0] < 2 * (SECTOR + RIM)
    assert SECTOR < per[1] < SECTOR + RIM
    assert swarm == pytest.approx(per[0], abs=1e-9)


@pytest.mark.parametrize(
    "obstacle",
    [
        ObstacleSpec(kind="tree", center_xy=(4.0, 0.0), height_m=4.0, radius_m=0.5),
        ObstacleSpec(kind="box", center_xy=(4.0, 0.0), height_m=4.0, half_extents_xy=(0.5, 0.5), yaw=0.4),
    ],
    ids=["tree", "box"],
)
def test_an_obstacle_casts_a_shadow_of_the_right_size(obstacle):
    """In front of the obstacle is seen, behind it is not; the area lost is the shadow's (a ring sector behind it)."""
    area = ObservedArea((obstacle,), (30.0, 30.0), 1, 85.0, 10.0)
    area.add_frame(0, camera(0.0, 0.0, 1.5, 0.0))
    assert cell_seen(area, 0, 2.0, 0.0) and not cell_seen(area, 0, 7.0, 0.0) and not cell_seen(area, 0, 4.0, 0.0)
    assert cell_seen(area, 0, 7.0, 2.5)  # beside the shadow
    # shadow: the angular width the obstacle subtends, from its near face to 10 m
    if obstacle.kind == "tree":
        half_angle, near = math.asin(0.5 / 4.0), 4.0 - 0.5
    else:
        corners = [np.array(obstacle.center_xy) + np.array([[math.cos(0.4), -math.sin(0.4)], [math.sin(0.4), math.cos(0.4)]]) @ (0.5 * np.array(s)) for s in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
        angles = [math.atan2(c[1], c[0]) for c in corners]
        half_angle, near = (max(angles) - min(angles)) / 2, min(float(np.linalg.norm(c)) for c in corners)
    shadow_max = half_angle * (10.0**2 - near**2)  # the ring sector from the nearest point: an upper bound
    lost = math.pi * 100.0 * 85.0 / 360.0 - area.areas_m2()[0][0]
    assert 0.6 * shadow_max < lost < 1.05 * shadow_max


def test_an_obstacle_lower_than_the_camera_does_not_block():
    low = ObstacleSpec(kind="tree", center_xy=(4.0, 0.0), height_m=1.0, radius_m=0.5)
    area = ObservedArea((low,), (30.0, 30.0), 1, 85.0, 10.0)
    area.add_frame(0, camera(0.0, 0.0, 1.5, 0.0))
    assert cell_seen(area, 0, 7.0, 0.0)


def test_rays_stop_at_the_raster_edge():
    area = ObservedArea((), (6.0, 6.0), 1, 85.0, 10.0)  # raster 10 x 10 m with its margin
    area.add_frame(0, camera(0.0, 0.0, 1.5, 0.0))
    assert area.areas_m2()[0][0] < math.pi * 100.0 * 85.0 / 360.0
    raster = area.raster()
    assert raster.extent() == pytest.approx((-5.0, 5.0, -5.0, 5.0))


@pytest.mark.slow
def test_a_flight_reports_s_obs_and_draws_it(tmp_path):
    """metrics.json holds S_obs per drone and for the swarm (the union: at least the largest, at most the sum); the plot is written."""
    import json

    import mpcde

    mpcde.fly("forest_swarm", mode="denied", seed=1, duration_s=2.0, out=tmp_path / "run")
    m = json.loads((tmp_path / "run" / "metrics.json").read_text())
    per, swarm = m["observed_area_m2"], m["observed_area_swarm_m2"]
    assert len(per) == 6 and all(a > 10.0 for a in per)
    assert max(per) <= swarm <= sum(per)
    assert (tmp_path / "run" / "observed_area.png").stat().st_size > 10_000
    assert "observed_area_m2" not in mpcde.fly("crossing", mode="comm", duration_s=0.5, cameras=False).metrics
