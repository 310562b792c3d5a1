"""Event trigger of MLR-DMPC (DMPC-Swarm Sec. 4.2.2, Eq. 11, Appendix A) against hand-computed priorities."""

from __future__ import annotations

import numpy as np
import pytest

from planners.dmpc.mlr.trigger import consensus, event_set, quantize, raw_priorities, selected_uav


def test_round_robin_priority_is_the_age_of_the_trajectory() -> None:
    # k = 10; trajectories computed in rounds 9, 4, -1 (initial): J = 1, 6, 11 (A1)
    np.testing.assert_allclose(raw_priorities("rr", 10, np.array([9, 4, -1]), np.array([5.0, 0.0, 1.0])), [1, 6, 11])


def test_distance_priority_is_the_distance_to_the_target() -> None:
    np.testing.assert_allclose(raw_priorities("db", 10, np.array([9, 4, -1]), np.array([0.5, 2.0, 0.0])), [0.5, 2, 0])


def test_hybrid_priority_is_distance_times_age() -> None:
    # A3: 0.5 * 1, 2.0 * 6, 0.3 * 11
    np.testing.assert_allclose(raw_priorities("ht", 10, np.array([9, 4, -1]), np.array([0.5, 2.0, 0.3])),
                               [0.5, 12.0, 3.3])
    with pytest.raises(ValueError, match="kind"):
        raw_priorities("xx", 0, np.zeros(1), np.zeros(1))


def test_quantisation_is_8_bit_and_keeps_zero_for_just_recomputed() -> None:
    q = quantize(np.array([0.0, 0.004, 0.03, 1.0, 100.0]), 0.02)  # round(x / 0.02), clipped to [1, 255]
    assert q.dtype == np.uint8
    np.testing.assert_array_equal(q, [1, 1, 2, 50, 255])


def test_consensus_takes_the_maximum_unless_any_cu_sent_zero() -> None:
    a = np.array([3, 0, 7, 1], np.uint8)
    b = np.array([5, 9, 2, 1], np.uint8)
    np.testing.assert_array_equal(consensus([a, b], 4), [5, 0, 7, 1])  # Eq. 11 with the zero rule
    np.testing.assert_array_equal(consensus([], 4), [0, 0, 0, 0])


def test_event_set_is_the_top_m_with_ties_to_the_lower_id() -> None:
    assert event_set(np.array([4, 9, 4, 0, 9], np.uint8), 3) == (1, 4, 0)


def test_cus_with_the_same_priorities_select_the_same_set_and_distinct_uavs() -> None:
    rng = np.random.default_rng(7)
    for k in range(50):
        m = int(rng.integers(1, 5))
        vectors = [rng.integers(0, 256, 12).astype(np.uint8) for _ in range(m)]
        sets = [event_set(consensus(vectors, 12), m) for _ in range(m)]  # every CU got every vector
        assert all(s == sets[0] for s in sets)
        picks = [selected_uav(sets[w], k, w, m) for w in range(m)]  # rank (k + w) mod M
        assert len(set(picks)) == m


def test_deadlock_aware_trigger_gives_priority_1_to_a_uav_held_away_from_its_target() -> None:
    """Appendix A: a recent computed trajectory that keeps its UAV in place short of its target -> priority 1."""
    from planners.dmpc.mlr.compute_unit import ComputeUnit
    from planners.dmpc.mlr.config import MlrConfig
    from planners.dmpc.mlr.tracker import TrackerEntry
    from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
    from planners.dmpc.mlr.uav import initial_trajectory

    starts = np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 2.0, 1.0], [2.0, 2.0, 1.0]])
    goals = starts + np.array([2.0, 0.0, 0.0])
    k = 50
    cfgs = {on: MlrConfig(n_uavs=4, n_cus=1, horizon_rounds=5, trigger="db", deadlock_trigger=on) for on in (False, True)}
    out = {}
    for on, cfg in cfgs.items():
        cu = ComputeUnit(cfg, 0, [initial_trajectory(cfg, p) for p in starts], goals)
        t0 = (k - 1) * cfg.round_s
        held = ReferenceTrajectory.hover(TrajectoryId(k - 2, 0), t0, starts[0], cfg.n_inputs, cfg.input_step_s)
        moving = ReferenceTrajectory(TrajectoryId(k - 2, 0), t0, np.r_[starts[1], 0.5, 0, 0, 0, 0, 0],
                                     np.zeros((cfg.n_inputs, 3)), cfg.input_step_s)  # 0.5 m/s along +x
        stale = ReferenceTrajectory.hover(TrajectoryId(k - 2 - cfg.deadlock_rounds, 0), t0, starts[2], cfg.n_inputs,
                                          cfg.input_step_s)  # held, but computed too long ago to count
        cu.trackers.entries = [TrackerEntry((held,)), TrackerEntry((moving,)), TrackerEntry((stale,)),
                               TrackerEntry((initial_trajectory(cfg, starts[3]),))]  # never computed: not counted
        out[on] = cu._priorities(k, None)
    assert out[False][0] == 100  # 2 m at 0.02 m per unit (A2)
    np.testing.assert_array_equal(out[True], [1, out[False][1], out[False][2], out[False][3]])
