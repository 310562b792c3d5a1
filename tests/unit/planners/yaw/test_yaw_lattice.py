"""Yaw lattice (MP-CDE Eq. 5): Dijkstra against brute-force enumeration, rate limit, cost shift."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from planners.yaw import YawPlannerConfig, edge_costs, shortest_path


def brute_force(cost: np.ndarray) -> tuple[float, list[tuple[int, ...]]]:
    """Cheapest total cost of all (2q + 1)^n hop sequences from candidate 0, and the hop sequences attaining it."""
    n, m, w = cost.shape
    q = (w - 1) // 2
    best, argbest = np.inf, []
    for hops in itertools.product(range(-q, q + 1), repeat=n):
        j, total = 0, 0.0
        for i, h in enumerate(hops):
            total += cost[i, j, h + q]
            j = (j + h) % m
        if total < best - 1e-12:
            best, argbest = total, [hops]
        elif abs(total - best) <= 1e-12:
            argbest.append(hops)
    return best, argbest


def path_cost(cost: np.ndarray, hops: np.ndarray) -> float:
    """Total cost of the hop sequence ``hops`` (n,) from candidate 0."""
    q = (cost.shape[2] - 1) // 2
    j, total = 0, 0.0
    for i, h in enumerate(hops):
        total += cost[i, j, h + q]
        j = (j + h) % cost.shape[1]
    return total


@pytest.mark.parametrize("n, m, q", [(1, 5, 1), (4, 7, 1), (5, 6, 1), (4, 9, 2), (3, 12, 2), (6, 4, 1)])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dijkstra_equals_brute_force_enumeration_of_all_paths(n, m, q, seed):
    cost = np.random.default_rng(seed).uniform(0.0, 1.0, (n, m, 2 * q + 1))
    best, argbest = brute_force(cost)
    path = shortest_path(cost)
    assert path.cost == pytest.approx(best, abs=1e-12)
    assert path_cost(cost, path.hops) == pytest.approx(best, abs=1e-12)
    assert tuple(int(h) for h in path.hops) in argbest
    assert path.candidates[0] == 0
    assert np.array_equal(path.candidates[1:], np.cumsum(path.hops) % m)


def test_every_step_of_the_lattice_path_obeys_the_rate_limit(rng):
    cfg = YawPlannerConfig()
    m, q, n = cfg.n_candidates, cfg.max_hop, cfg.n_steps
    cost = rng.uniform(0.0, 1.0, (n, m, 2 * q + 1))
    path = shortest_path(cost)
    yaws = cfg.candidate_spacing_rad * np.concatenate([[0.0], np.cumsum(path.hops)])
    assert np.all(np.abs(path.hops) <= q)
    assert np.all(np.abs(np.diff(yaws)) <= cfg.yaw_rate_max_radps * cfg.period_s + 1e-12)


def test_default_lattice_can_hold_and_turn_at_nearly_full_rate():
    cfg = YawPlannerConfig()
    assert cfg.max_hop == 2
    assert cfg.max_hop * cfg.candidate_spacing_rad <= cfg.max_step_rad
    assert cfg.max_hop * cfg.candidate_spacing_rad > 0.95 * cfg.max_step_rad


def test_shifted_costs_keep_the_maximum_reward_path(rng):
    """Adding alpha + beta to every edge (all paths have n edges) does not change which path is best."""
    n, m, q = 4, 7, 1
    e = rng.uniform(0.0, 1.0, (n, m, 2 * q + 1))
    v = rng.uniform(0.0, 1.0, (n, m))
    alpha, beta = 0.6, 0.4
    cost = edge_costs(e, v, alpha, beta, turn_penalty=0.0)
    assert np.all(cost >= 0.0)
    reward = -(cost - (alpha + beta))  # alpha E + beta V of each edge, Eq. 5 with the sign undone
    best_reward = max(
        sum(reward[i, j, h + q] for i, h, j in zip(range(n), hops, np.cumsum((0,) + hops)[:-1] % m))
        for hops in itertools.product(range(-q, q + 1), repeat=n)
    )
    path = shortest_path(cost)
    assert n * (alpha + beta) - path.cost == pytest.approx(best_reward, abs=1e-12)


def test_edge_cost_reads_V_at_the_head_node_of_the_edge():
    n, m, q = 2, 5, 1
    e = np.zeros((n, m, 2 * q + 1))
    v = np.zeros((n, m))
    v[0, 4] = 1.0  # layer 1, candidate 4 = one hop right of candidate 0
    cost = edge_costs(e, v, alpha=0.6, beta=0.4, turn_penalty=0.0)
    assert cost[0, 0, 0] == pytest.approx(0.6)  # 0 -> 4 (h = -1): V = 1 earns beta
    assert cost[0, 0, 1] == pytest.approx(1.0)  # 0 -> 0
    assert shortest_path(cost).hops[0] == -1


def test_negative_or_non_finite_costs_are_refused():
    with pytest.raises(ValueError, match="cost"):
        shortest_path(-np.ones((2, 5, 3)))
    with pytest.raises(ValueError, match="cost"):
        shortest_path(np.full((2, 5, 3), np.nan))
