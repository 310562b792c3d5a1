"""Neighbour-by-neighbour fusion of radio plans and camera tracks (closed-form cases)."""

import numpy as np
import pytest

from mpcde.config.auto import FusionConfig
from mpcde.onboard.fusion import fuse_neighbours, unknown_neighbour_id
from perception.types import NeighborPrediction

T = 10.0
STALE, GATE, VMAX = 0.5, 1.0, 2.0


def _plan(sender: int, sent_s: float, pos, vel=(0.0, 0.0, 0.0)) -> NeighborPrediction:
    return NeighborPrediction.constant_velocity(sender, "radio", sent_s, np.asarray(pos, float), np.asarray(vel, float), np.zeros((6, 6)))


def _track(track_id: int, pos, seen_s: float = T) -> NeighborPrediction:
    return NeighborPrediction.constant_velocity(track_id, "perception", seen_s, np.asarray(pos, float), np.zeros(3), np.eye(6) * 0.01)


def _fuse(plans, tracks):
    return fuse_neighbours(plans, tracks, T, STALE, GATE, VMAX)


def test_a_track_of_a_drone_with_a_fresh_plan_is_dropped_for_the_plan():
    plan = _plan(3, T - 0.2, [1.0, 2.0, 1.5])
    f = _fuse([plan], [_track(7, [1.3, 2.1, 1.5])])
    assert f.predictions == [plan]
    assert (f.fresh_plans, f.stale_plans, f.substituted, f.unknown_tracks, f.explained_tracks) == (1, 0, 0, 0, 1)


def test_a_plan_exactly_stale_after_s_old_is_still_fresh():
    f = _fuse([_plan(3, T - STALE, [0.0, 0.0, 1.5])], [])
    assert f.fresh_plans == 1 and f.stale_plans == 0


def test_a_stale_plan_is_replaced_by_the_track_that_matches_it_and_keeps_the_sender_id():
    # plan sent 1.5 s ago: gate = 1.0 + 2.0 * 1.5 = 4.0 m; the track is 3.5 m from where the plan says
    track = _track(7, [3.5, 0.0, 1.5])
    f = _fuse([_plan(3, T - 1.5, [0.0, 0.0, 1.5])], [track])
    assert (f.fresh_plans, f.stale_plans, f.substituted, f.unknown_tracks) == (0, 0, 1, 0)
    (p,) = f.predictions
    assert p.neighbor_id == 3 and p.source == "perception"
    np.testing.assert_array_equal(p.pos_world, track.pos_world)


def test_a_stale_plan_without_a_track_in_its_gate_is_kept_and_the_far_track_is_an_unknown_drone():
    plan = _plan(3, T - 1.0, [0.0, 0.0, 1.5])  # gate 3.0 m
    f = _fuse([plan], [_track(7, [3.2, 0.0, 1.5])])
    assert (f.stale_plans, f.substituted, f.unknown_tracks) == (1, 0, 1)
    assert f.predictions[0] is plan
    assert f.predictions[1].neighbor_id == unknown_neighbour_id(7) == -8


def test_one_track_substitutes_at_most_one_stale_plan():
    plans = [_plan(1, T - 1.0, [0.0, 0.0, 1.5]), _plan(2, T - 1.0, [0.5, 0.0, 1.5])]
    f = _fuse(plans, [_track(4, [0.1, 0.0, 1.5])])
    assert (f.substituted, f.stale_plans, f.unknown_tracks) == (1, 1, 0)
    assert [p.neighbor_id for p in f.predictions] == [1, 2]
    assert f.predictions[0].source == "perception"  # the nearer plan gets the track


def test_a_track_explained_by_a_fresh_plan_cannot_also_substitute_a_stale_one():
    fresh, stale = _plan(1, T - 0.2, [0.0, 0.0, 1.5]), _plan(2, T - 1.0, [0.4, 0.0, 1.5])
    f = _fuse([fresh, stale], [_track(4, [0.05, 0.0, 1.5])])
    assert (f.fresh_plans, f.explained_tracks, f.substituted, f.stale_plans) == (1, 1, 0, 1)
    assert f.predictions == [fresh, stale]


def test_plans_are_matched_at_the_round_time_not_at_their_stamp():
    # the plan says the neighbour moves at 1 m/s along x since it was sent 0.4 s ago: now at x = 0.4
    plan = _plan(3, T - 0.4, [0.0, 0.0, 1.5], vel=[1.0, 0.0, 0.0])
    assert _fuse([plan], [_track(7, [1.3, 0.0, 1.5])]).explained_tracks == 1  # 0.9 m from the plan now
    assert _fuse([plan], [_track(7, [-0.7, 0.0, 1.5])]).explained_tracks == 0  # 0.7 m from the stamp, 1.1 m now


def test_every_plan_is_counted_once():
    rng = np.random.default_rng(0)
    plans = [_plan(j, T - rng.uniform(0.0, 2.0), rng.uniform(-3, 3, 3)) for j in range(6)]
    tracks = [_track(10 + i, rng.uniform(-3, 3, 3)) for i in range(5)]
    f = _fuse(plans, tracks)
    assert f.fresh_plans + f.stale_plans + f.substituted == len(plans)
    assert f.explained_tracks + f.substituted + f.unknown_tracks == len(tracks)
    assert len(f.predictions) == len(plans) + f.unknown_tracks


@pytest.mark.parametrize("field, value", [("stale_after_s", 0.0), ("gate_m", -1.0), ("gate_m", float("nan"))])
def test_invalid_fusion_settings_are_refused_with_the_field_name(field, value):
    with pytest.raises(ValueError, match=f"^{field}="):
        FusionConfig(**{field: value})
