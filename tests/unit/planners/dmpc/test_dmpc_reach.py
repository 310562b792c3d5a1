"""Reach boxes of the DMPC QP contain every feasible plan; implied half-spaces hold on them."""

from __future__ import annotations

import numpy as np
import pytest

from planners.dmpc.config import DmpcConfig
from planners.dmpc.model import rollout
from planners.dmpc.reach import implied_half_spaces, reach_boxes


@pytest.mark.parametrize("model", ["double", "triple"])
def test_every_input_within_the_limits_stays_in_both_boxes(model: str, rng: np.random.Generator) -> None:
    cfg = DmpcConfig(model=model)
    K = cfg.horizon_steps
    x0 = np.zeros(cfg.state_dim)
    x0[:3], x0[3:6] = [0.5, -1.0, 1.5], [1.5, -0.4, 0.1]
    if model == "triple":
        x0[6:9] = [1.0, -1.0, 0.0]
    boxes = reach_boxes(cfg, x0)
    h, checked, tight = cfg.step_s, 0, np.zeros(2)
    for _ in range(400):
        # Random inputs, clipped step by step to the QP's limits (often saturated: towards the boxes' corners).
        state, inputs, ok = x0.copy(), np.zeros((K, 3)), True
        for k in range(K):
            v, a = state[3:6], state[6:9] if model == "triple" else 0.0
            want = rng.choice([-1.0, 1.0], 3) * rng.uniform(0.5, 2.0, 3) if model == "double" else rng.uniform(-1.0, 1.0, 3)
            if model == "double":  # |u| <= a_max_mps2 and |v + h u| <= v_max_mps
                lo, hi = np.maximum(-cfg.limits.a_max_mps2, (-cfg.limits.v_max_mps - v) / h), np.minimum(cfg.limits.a_max_mps2, (cfg.limits.v_max_mps - v) / h)
                want = want * cfg.limits.a_max_mps2
            else:  # |j| <= j_max_mps3, |a + h j| <= a_max_mps2, |v + h a + h^2 j / 2| <= v_max_mps
                lo = np.maximum.reduce([np.full(3, -cfg.limits.j_max_mps3), (-cfg.limits.a_max_mps2 - a) / h, (-cfg.limits.v_max_mps - v - h * a) / (h * h / 2)])
                hi = np.minimum.reduce([np.full(3, cfg.limits.j_max_mps3), (cfg.limits.a_max_mps2 - a) / h, (cfg.limits.v_max_mps - v - h * a) / (h * h / 2)])
                want = want * cfg.limits.j_max_mps3
            if np.any(lo > hi):
                ok = False
                break
            inputs[k] = np.clip(want, lo, hi)
            state = rollout(model, h, state, inputs[k : k + 1])[1]
        if not ok:
            continue
        states = rollout(model, h, x0, inputs)
        assert np.all(np.abs(states[1:, 3:6]) <= cfg.limits.v_max_mps + 1e-9)
        checked += 1
        for b, (centre, half) in enumerate(boxes):
            excess = np.abs(states[1:, :3] - centre) - half
            assert np.all(excess <= 1e-9)
            tight[b] = max(tight[b], (np.abs(states[1:, :3] - centre) / half).max())
    assert checked > (100 if model == "double" else 10)  # greedy clipping often dead-ends for the triple chain
    assert np.all(tight > 0.5)  # the boxes are not vacuous


def test_implied_half_space_needs_the_whole_box_and_the_margin() -> None:
    centre, half = np.zeros((2, 3)), np.full((2, 3), 1.0)
    normals = np.array([[[1.0, 0, 0], [1.0, 0, 0]], [[0.6, 0.8, 0], [0.6, 0.8, 0]]])
    # x >= -1.05 holds on [-1, 1]^3 with 5 cm spare; x >= -0.9 does not; 0.6x + 0.8y >= -1.45 spares 5 cm.
    offsets = np.array([[-1.05, -0.9], [-1.45, -1.39]])
    got = implied_half_spaces(normals, offsets, [(centre, half)], 0.01)
    np.testing.assert_array_equal(got, [[True, False], [True, False]])
    assert not implied_half_spaces(normals, offsets, [(centre, half)], 0.1)[0, 0]
