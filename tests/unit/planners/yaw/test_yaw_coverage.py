"""Occlusion-aware FoV sectors and the exploration metric E (MP-CDE Eq. 3)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from perception.types import OccupancySnapshot
from planners.yaw import (
    FanGeometry,
    YawPlannerConfig,
    cast_fans,
    edge_gains,
    past_coverage,
    ray_gains,
    visible_cells_xy,
)

VOXEL_M = 0.2


def snapshot(state: np.ndarray, origin=(-6.0, -6.0, 0.0)) -> OccupancySnapshot:
    """Snapshot with the given state; the distance layers are not read by the coverage code."""
    zeros = np.zeros(state.shape, np.float32)
    return OccupancySnapshot(0.0, np.asarray(origin, float), VOXEL_M, state.astype(np.int8), zeros, zeros)


def test_fan_partitions_the_circle_into_sectors_of_n_rays():
    cfg = YawPlannerConfig()
    fan = FanGeometry.from_config(cfg)
    assert fan.n_fan * fan.dtheta_rad == pytest.approx(2 * math.pi)
    assert fan.n_sector * fan.dtheta_rad == pytest.approx(cfg.fov_h_rad, rel=1e-3)
    az = fan.azimuths(0.3)[: fan.n_sector]
    assert np.mean(az) == pytest.approx(0.3)  # the sector of yaw0 is centred on it
    # a full unoccluded sector has area fov R^2 / 2
    assert fan.n_sector * fan.areas_m2.sum() == pytest.approx(0.5 * cfg.fov_h_rad * cfg.sensing_range_m**2, rel=1e-2)


def test_rays_stop_at_the_first_occupied_voxel():
    state = np.full((60, 60, 10), OccupancySnapshot.UNKNOWN)
    state[40, 28:33, :] = OccupancySnapshot.OCCUPIED  # a short wall 2.1 m ahead (+x) of the drone at (0.1, 0.1)
    snap = snapshot(state)
    ranges = (np.arange(25) + 0.5) * 0.2
    cast = cast_fans(snap, np.array([[0.1, 0.1, 1.1]]), np.array([0.0, math.pi / 2]), ranges)
    ahead, left = cast.visible[0]
    assert ahead[ranges < 1.9].all() and not ahead[ranges > 2.1].any()  # occluded behind the wall
    assert left.all()  # nothing in the way to the left
    assert cast.unknown[0, 1].all()


def test_outside_the_window_reads_unknown_and_is_never_covered():
    state = np.zeros((20, 20, 10))
    snap = snapshot(state, origin=(-2.0, -2.0, 0.0))
    ranges = (np.arange(25) + 0.5) * 0.2
    cast = cast_fans(snap, np.array([[0.1, 0.1, 1.1]]), np.array([0.0]), ranges)
    outside = 0.1 + ranges >= 2.0  # the window spans x in [-2, 2)
    assert cast.unknown[0, 0, outside].all() and not cast.unknown[0, 0, ~outside].any()
    covered = past_coverage(snap, np.array([[5.0, 0.1], [0.1, 0.1]]))  # one point outside, one inside
    assert covered.sum() == 1
    assert not covered[cast.cell[0, 0, outside]].any()


def test_edge_gain_is_the_area_of_the_new_sector_outside_the_predecessor_sector(rng):
    """E of edge j -> k equals the sum over the rays of k's sector that are not in j's sector (explicit sets)."""
    cfg = YawPlannerConfig()
    fan = FanGeometry.from_config(cfg)
    m, q = cfg.n_candidates, cfg.max_hop
    gains = rng.uniform(0.0, 1.0, (3, fan.n_fan))
    e, e_max = edge_gains(gains, fan, m, q)

    def sector(k: int) -> set[int]:
        start = int(round(k * fan.n_fan / m))
        return {(start + r) % fan.n_fan for r in range(fan.n_sector)}

    for i in range(3):
        for j in range(m):
            for h in range(-q, q + 1):
                new = sector(j + h) - sector(j)
                assert e[i, j, h + q] == pytest.approx(sum(gains[i, r] for r in new), abs=1e-9)
    assert np.all(e[:, :, q] == 0.0)  # holding the yaw sees nothing new
    # the bound: the widest swept strip, all of it gained
    full = edge_gains(np.ones((1, fan.n_fan)) * fan.areas_m2.sum(), fan, m, q)[0]
    assert e_max == pytest.approx(full.max())


def test_known_space_and_the_coverage_window_earn_nothing():
    state = np.full((60, 60, 10), OccupancySnapshot.UNKNOWN)
    state[:, :30] = OccupancySnapshot.FREE  # y < 0 known free, y >= 0 unknown
    snap = snapshot(state)
    fan = FanGeometry.from_config(YawPlannerConfig())
    pos = np.array([[0.1, -0.1, 1.1]])  # in a free voxel just right of the boundary
    cast = cast_fans(snap, pos, fan.azimuths(0.0), fan.ranges_m)
    none = np.zeros_like(past_coverage(snap, np.zeros((0, 2))))
    g = ray_gains(cast, none, fan.areas_m2)[0]
    az = (fan.azimuths(0.0) + np.pi) % (2 * np.pi) - np.pi
    assert np.all(g[(az < -0.2) & (az > -np.pi + 0.2)] == 0.0)  # rays into the known free half
    assert np.all(g[(az > 0.2) & (az < np.pi - 0.2)] > 0.0)  # rays into the unknown half
    # the sector of yaw +pi/2, once in the window, no longer counts
    left = cast_fans(snap, pos, fan.azimuths(math.pi / 2)[: fan.n_sector], fan.ranges_m)
    covered = past_coverage(snap, visible_cells_xy(snap, left))
    g_after = ray_gains(cast, covered, fan.areas_m2)[0]
    in_sector = np.abs((az - math.pi / 2 + np.pi) % (2 * np.pi) - np.pi) < 0.5 * np.radians(85) - 0.05
    # (up to cells that the window's rays, at other azimuths, cut past at a corner)
    assert g_after[in_sector].sum() <= 0.02 * g[in_sector].sum()
    far = np.abs(az - math.pi / 2) > 1.0  # rays well outside that sector keep their gain (but for the apex cells)
    np.testing.assert_allclose(g_after[far], g[far], rtol=0.01)
