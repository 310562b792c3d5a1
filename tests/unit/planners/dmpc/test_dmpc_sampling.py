"""Vectorised plan sampling equals the per-plan interpolants it replaces (NeighborPrediction, DmpcPlan)."""

from __future__ import annotations

import numpy as np
import pytest

from perception.types import NeighborPrediction
from planners.dmpc.sampling import hermite_positions, sample_predictions
from planners.dmpc.types import DmpcPlan


def _prediction(rng: np.random.Generator, n_samples: int, t0: float, neighbor_id: int) -> NeighborPrediction:
    times = t0 + np.cumsum(rng.uniform(0.1, 0.3, n_samples))
    return NeighborPrediction(
        neighbor_id=neighbor_id, source="radio", stamp_s=float(times[0]), times_s=times,
        pos_world=rng.normal(size=(n_samples, 3)), vel_world=rng.normal(size=(n_samples, 3)),
        cov_world=np.zeros((6, 6)),
    )  # fmt: skip


def test_sample_predictions_matches_neighbor_prediction_position(rng: np.random.Generator) -> None:
    # Mixed lengths (1-sample tracks and 16-sample plans) and stamps; query times before, inside, at and after.
    preds = [_prediction(rng, n, t0, i) for i, (n, t0) in enumerate([(16, 0.0), (1, 0.5), (16, -0.7), (3, 1.0), (16, 0.2)])]
    t = np.r_[np.linspace(-2.0, 6.0, 97), preds[0].times_s, preds[3].times_s]
    got = sample_predictions(preds, t)
    want = np.stack([p.position(t) for p in preds])
    assert got.shape == (5, t.size, 3)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_empty_list_gives_an_empty_array() -> None:
    assert sample_predictions([], np.arange(4.0)).shape == (0, 4, 3)


@pytest.mark.parametrize("t0", [0.0, 0.3])
def test_hermite_positions_matches_dmpc_plan_position(rng: np.random.Generator, t0: float) -> None:
    K, h = 15, 0.2
    plan = DmpcPlan(t0, h, rng.normal(size=(K + 1, 3)), rng.normal(size=(K + 1, 3)), np.zeros((K + 1, 3)))
    t = np.r_[np.linspace(t0 - 0.5, t0 + K * h + 1.0, 203), plan.times_s]
    got = hermite_positions(plan.times_s[None], plan.pos_world[None], plan.vel_world[None], t)[0]
    np.testing.assert_allclose(got, plan.position(t), rtol=0, atol=1e-12)
