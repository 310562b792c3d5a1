"""Visibility metric V of the exploring mode (MP-CDE Eq. 4)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from perception.types import NeighborPrediction
from planners.yaw import YawPlannerConfig, layer_weights, visibility_rewards

CFG = YawPlannerConfig()
N = CFG.n_steps
TIMES = 0.1 * np.arange(1, N + 1)
POSITIONS = np.tile([0.0, 0.0, 1.0], (N, 1))
YAWS = np.linspace(-math.pi, math.pi, 72, endpoint=False)


def track(pos, sigma_m: float = 0.05, vel=(0.0, 0.0, 0.0), nid: int = 0, stamp_s: float = -1.0) -> NeighborPrediction:
    """A track last updated at ``stamp_s`` at ``pos`` (3,) [m], position standard deviation ``sigma_m``."""
    cov = np.diag([sigma_m**2] * 3 + [0.0] * 3)
    return NeighborPrediction.constant_velocity(nid, "perception", stamp_s, np.asarray(pos, float), vel, cov)


def plateau_centre(v_row: np.ndarray) -> float:
    """Circular mean [rad] of the candidate yaws whose reward is within 0.1 % of the row's maximum."""
    top = YAWS[v_row >= 0.999 * v_row.max()]
    return math.atan2(np.sin(top).sum(), np.cos(top).sum())


def test_no_neighbours_no_reward():
    assert np.all(visibility_rewards(POSITIONS, TIMES, YAWS, [], CFG) == 0.0)


def test_reward_is_largest_for_yaws_that_see_the_neighbour_and_zero_far_outside_the_fov():
    v = visibility_rewards(POSITIONS, TIMES, YAWS, [track((0.0, 3.0, 1.0))], CFG)
    assert v.max() == pytest.approx(1.0)
    assert plateau_centre(v[0]) == pytest.approx(math.pi / 2, abs=math.pi / 72)
    width = np.count_nonzero(v[0] >= 0.5 * v[0].max()) * 2 * math.pi / 72
    assert abs(width - CFG.fov_h_rad) <= 2 * math.pi / 72  # the neighbour is in view for yaws within +-fov/2
    outside = np.abs((YAWS - math.pi / 2 + math.pi) % (2 * math.pi) - math.pi) > 0.5 * CFG.fov_h_rad + 0.3
    assert np.all(v[:, outside] < 1e-6)


def test_an_uncertain_neighbour_rewards_centring_it():
    v = visibility_rewards(POSITIONS, TIMES, YAWS, [track((0.0, 3.0, 1.0), sigma_m=0.6)], CFG)
    assert YAWS[np.argmax(v[0])] == pytest.approx(math.pi / 2, abs=math.pi / 72)
    assert v[0, np.argmin(np.abs(YAWS - math.pi / 2 + 0.6))] < 0.9 * v[0].max()  # near the edge: less


def test_triangular_kernel_emphasises_the_near_term():
    w = layer_weights(N)
    assert w[0] == 1.0 and w[-1] == pytest.approx(1.0 / N) and np.all(np.diff(w) < 0)
    v = visibility_rewards(POSITIONS, TIMES, YAWS, [track((0.0, 3.0, 1.0))], CFG)
    k = np.argmax(v[0])
    np.testing.assert_allclose(v[:, k], w)  # a still neighbour: only the kernel changes over the layers


def test_nearer_neighbours_and_stale_tracks_weigh_more():
    near, far = track((0.0, 1.0, 1.0), nid=0), track((0.0, -4.0, 1.0), nid=1)
    v = visibility_rewards(POSITIONS, TIMES, YAWS, [near, far], CFG)
    left, right = np.argmin(np.abs(YAWS - math.pi / 2)), np.argmin(np.abs(YAWS + math.pi / 2))
    ratio = v[0, left] / v[0, right]
    assert ratio == pytest.approx((4.0 + CFG.distance_eps_m) / (1.0 + CFG.distance_eps_m), rel=1e-3)
    # the same two at equal distance; the right one's covariance inflated (not seen for long)
    fresh, stale = track((0.0, 3.0, 1.0), sigma_m=0.05, nid=0), track((0.0, -3.0, 1.0), sigma_m=0.8, nid=1)
    v = visibility_rewards(POSITIONS, TIMES, YAWS, [fresh, stale], CFG)
    assert v[0, right] > 1.5 * v[0, left]


def test_neighbours_outside_the_vertical_fov_or_the_range_are_not_visible():
    above = track((3.0, 0.0, 1.0 + 3.0 * math.tan(math.radians(35))))  # 35 deg up > 29 deg half vertical FoV
    beyond = track((CFG.detection_range_m + 0.5, 0.0, 1.0))
    assert np.all(visibility_rewards(POSITIONS, TIMES, YAWS, [above], CFG) == 0.0)
    assert np.all(visibility_rewards(POSITIONS, TIMES, YAWS, [beyond], CFG) == 0.0)


def test_the_indicator_follows_the_predicted_motion():
    mover = track((3.0, -1.5, 1.0), vel=(0.0, 3.0, 0.0), stamp_s=0.0)  # crosses in front, from right to left
    v = visibility_rewards(POSITIONS, TIMES, YAWS, [mover], CFG)
    assert plateau_centre(v[0]) == pytest.approx(math.atan2(-1.2, 3.0), abs=math.pi / 72)
    assert plateau_centre(v[-1]) == pytest.approx(math.atan2(-1.5 + 3.0 * 1.2, 3.0), abs=math.pi / 72)
