"""TrackingScore: closed-form errors, false tracks and the awareness fraction."""

import numpy as np
import pytest

from mpcde.flight.tracking_score import TrackingScore
from perception.types import NeighborPrediction


def _pred(i, p, v, t=0.0):
    return NeighborPrediction.constant_velocity(i, "perception", t, np.asarray(p, float), np.asarray(v, float), np.eye(6) * 1e-4)


POS = np.array([[0.0, 0.0, 1.5], [2.0, 0.0, 1.5], [0.0, 5.0, 1.5]])
VEL = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def test_rmse_of_matched_predictions_is_the_closed_form_one():
    s = TrackingScore(match_gate_m=1.0, near_m=3.0)
    # drone 0 sees drone 1 with a 0.3 m position and 0.4 m/s velocity error, drone 2 with 0.1 m, exact velocity;
    # the predictions are given in the opposite order to the truth (the matching must sort them out)
    preds = [_pred(7, POS[2] + [0.1, 0.0, 0.0], VEL[2]), _pred(3, POS[1] + [0.0, 0.3, 0.0], VEL[1] + [0.0, 0.0, 0.4])]
    s.update(0, preds, 0.0, POS, VEL, np.ones(3, bool))
    r = s.result()
    assert r["track_samples"] == 2 and r["false_track_samples"] == 0
    assert r["tracking_pos_rmse_m"] == pytest.approx(np.sqrt((0.3**2 + 0.1**2) / 2))
    assert r["tracking_vel_rmse_mps"] == pytest.approx(np.sqrt(0.4**2 / 2))
    assert r["neighbours_tracked_fraction"] == pytest.approx(1.0)  # drone 1 is the only one within 3 m, and tracked


def test_a_prediction_out_of_the_gate_is_false_and_an_untracked_near_neighbour_counts_as_missed():
    s = TrackingScore(match_gate_m=1.0, near_m=3.0)
    s.update(0, [_pred(1, [10.0, 10.0, 1.5], [0.0, 0.0, 0.0])], 0.0, POS, VEL, np.ones(3, bool))
    r = s.result()
    assert r["track_samples"] == 0 and r["false_track_samples"] == 1 and r["tracking_pos_rmse_m"] is None
    assert r["neighbours_tracked_fraction"] == 0.0


def test_predictions_are_read_at_the_scoring_time_and_failed_drones_are_not_neighbours():
    s = TrackingScore()
    # a prediction stamped 1 s earlier, 1 m/s along x, that lands on drone 1 at t = 1
    s.update(0, [_pred(1, POS[1] - [1.0, 0.0, 0.0], VEL[1], t=0.0)], 1.0, POS, VEL, np.array([True, True, False]))
    r = s.result()
    assert r["tracking_pos_rmse_m"] == pytest.approx(0.0, abs=1e-12)
    s2 = TrackingScore()
    s2.update(0, [_pred(1, POS[1], VEL[1])], 0.0, POS, VEL, np.array([True, False, True]))
    assert s2.result()["false_track_samples"] == 1  # the only drone near it has failed


def test_no_perceiving_agent_gives_no_metrics():
    assert TrackingScore().result() == {}
