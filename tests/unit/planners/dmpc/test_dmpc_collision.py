"""Collision geometry of the DMPC QP: on-demand planes (on-demand DMPC Sec. 3.4) and BVC (DMPC-Swarm Eq. 14-15)."""

from __future__ import annotations

import numpy as np
import pytest

from planners.dmpc.collision import (
    bvc_planes,
    ellipsoidal_distance,
    first_conflict_step,
    on_demand_constraints,
)

R_MIN, C = 0.4, 2.0


def _line(start: np.ndarray, vel: np.ndarray, n: int = 60, dt: float = 0.05) -> np.ndarray:
    return np.asarray(start, float) + np.asarray(vel, float) * (dt * np.arange(1, n + 1))[:, None]


def test_ellipsoidal_distance_scales_the_vertical_axis_by_the_downwash_factor() -> None:
    d = np.array([[R_MIN, 0, 0], [0, R_MIN, 0], [0, 0, C * R_MIN], [0.3, 0.0, 0.8]])
    np.testing.assert_allclose(ellipsoidal_distance(d, C), [R_MIN, R_MIN, R_MIN, 0.5])


def test_first_conflict_step_finds_the_first_time_below_the_threshold() -> None:
    own = _line([0, 0, 1], [1, 0, 0])
    other = _line([4, 0, 1], [-1, 0, 0])  # closing at 2 m/s, gap 4 - 0.1 k
    k = first_conflict_step(own, other[None], R_MIN, C)
    gaps = np.linalg.norm(own - other, axis=1)
    assert gaps[k] < R_MIN <= gaps[k - 1]
    assert first_conflict_step(own, (other + [0, 5, 0])[None], R_MIN, C) == -1
    assert first_conflict_step(own, np.zeros((0, 60, 3)), R_MIN, C) == -1


@pytest.mark.parametrize("rule", ["first_conflict", "closest_approach"])
def test_a_neighbour_dead_ahead_yields_a_plane_that_separates_the_two(rule: str, rng: np.random.Generator) -> None:
    own = _line([0, 0, 1.5], [1.5, 0, 0])
    other = _line([5, 0.05, 1.5], [-1.5, 0, 0])
    cons = on_demand_constraints(own, other[None], R_MIN, C, 0.05, 3.0, linearise_at=rule)
    assert cons.count == 1 and cons.step_index >= 0
    k = cons.time_index[0]
    a, b = cons.normal[0], cons.offset[0]
    p_j = other[k]
    # The neighbour's predicted position is strictly on the other side, by at least r_min_m.
    assert a @ p_j <= b - R_MIN + 1e-12
    # Every point on the free side is at least r_min_m away (the linearisation is a lower bound).
    pts = p_j + rng.uniform(-2, 2, size=(20000, 3))
    free = pts @ a >= b
    assert free.sum() > 1000
    assert ellipsoidal_distance(pts[free] - p_j, C).min() >= R_MIN - 1e-12
    # The plane passes at distance r_min_m from p_j along its normal (tight).
    foot = p_j + (b - a @ p_j) * a / (a @ a)
    assert ellipsoidal_distance(foot - p_j, C) <= R_MIN + 1e-9 + np.linalg.norm(foot - p_j) * (1 - 1 / C)


def test_closest_approach_rule_pushes_sideways_and_first_conflict_rule_pushes_back() -> None:
    own = _line([0, 0, 1.5], [1.5, 0, 0])
    other = _line([4.5, 0.05, 1.5], [-1.5, 0, 0])  # nearly head-on, 5 cm lateral offset, meet at t = 1.5 s
    first = on_demand_constraints(own, other[None], R_MIN, C, 0.05, 3.0, linearise_at="first_conflict")
    closest = on_demand_constraints(own, other[None], R_MIN, C, 0.05, 3.0, linearise_at="closest_approach")
    assert abs(first.normal[0, 0]) > 0.9  # along the approach
    assert abs(closest.normal[0, 1]) > 0.9  # across it
    assert closest.time_index[0] > first.time_index[0] == first.step_index


def test_only_neighbours_within_the_neighbourhood_are_constrained() -> None:
    own = _line([0, 0, 1.5], [1.0, 0, 0])
    conflicting = _line([3, 0.1, 1.5], [-1.0, 0, 0])
    far = _line([0, 3, 1.5], [0.0, 0, 0])  # never near
    near = _line([1.5, 0.9, 1.5], [0.0, 0, 0])  # 0.9 m from the conflict point < 3 r_min_m = 1.2 m
    cons = on_demand_constraints(own, np.stack([conflicting, far, near]), R_MIN, C, 0.05, 3.0)
    assert set(cons.neighbour_index.tolist()) == {0, 2}
    none = on_demand_constraints(own, far[None], R_MIN, C, 0.05, 3.0)
    assert none.count == 0 and none.step_index == -1


def test_coincident_predictions_fall_back_to_the_current_separation() -> None:
    own = np.tile([1.0, 0.0, 1.0], (10, 1))
    cons = on_demand_constraints(
        own, own[None].copy(), R_MIN, C, 0.05, 3.0, own_now_world=np.array([1.0, 0, 1]),
        neighbours_now_world=np.array([[1.0, -1.0, 1.0]]),
    )  # fmt: skip
    assert np.all(np.isfinite(cons.normal)) and cons.normal[0] @ [0, 1, 0] > 0.99


def test_bvc_planes_separate_both_drones_by_r_min(rng: np.random.Generator) -> None:
    K, M = 15, 4
    own = rng.uniform(-2, 2, size=(K, 3))
    others = rng.uniform(-2, 2, size=(M, K, 3))
    mine = bvc_planes(own, others, R_MIN, C)
    assert mine.normal.shape == (M, K, 3) and mine.offset.shape == (M, K)
    for m in range(M):
        theirs = bvc_planes(others[m], own[None], R_MIN, C)
        for k in range(K):
            a_i, b_i = mine.normal[m, k], mine.offset[m, k]
            a_j, b_j = theirs.normal[0, k], theirs.offset[0, k]
            np.testing.assert_allclose(a_i, -a_j, atol=1e-12)  # the same plane, seen from both sides
            p_i = own[k] + rng.uniform(-3, 3, size=(4000, 3))
            p_j = others[m, k] + rng.uniform(-3, 3, size=(4000, 3))
            p_i, p_j = p_i[p_i @ a_i >= b_i], p_j[p_j @ a_j >= b_j]
            n = min(len(p_i), len(p_j))
            if n:  # any two points in the two cells are r_min_m apart (Eq. 15 sums to r_min_m)
                assert ellipsoidal_distance(p_i[:n] - p_j[:n], C).min() >= R_MIN - 1e-9
            gap = ellipsoidal_distance(own[k] - others[m, k], C)
            # the previous own position is inside its cell iff the previous plans were r_min_m apart
            assert (own[k] @ a_i >= b_i - 1e-12) == (gap >= R_MIN - 1e-12)


def test_bvc_plane_is_midway_between_the_previous_positions_in_scaled_space() -> None:
    own = np.array([[0.0, 0.0, 1.0]])
    other = np.array([[[2.0, 0.0, 1.0]]])
    planes = bvc_planes(own, other, R_MIN, C)
    np.testing.assert_allclose(planes.normal[0, 0], [-1, 0, 0], atol=1e-12)
    # -x >= (r_min_m + 2)/2 - 2  ->  x <= 1 - r_min_m/2
    np.testing.assert_allclose(-planes.offset[0, 0], 1.0 - R_MIN / 2)
