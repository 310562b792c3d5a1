"""Neighbour capsules in the front end's copy of the ESDF: exact distances, inflation of unseen tracks, no side effects."""

import numpy as np
import pytest

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.neighbour_field import with_neighbour_capsules


def _empty(truncation=3.0):
    shape = (40, 40, 20)
    return OccupancySnapshot(
        time_s=0.0, origin_world=np.array([-3.0, -3.0, 0.0]), voxel_m=0.15, state=np.zeros(shape, np.int8),
        distance_m=np.full(shape, truncation, np.float32), free_distance_m=np.full(shape, truncation, np.float32),
    )


def _nb(p, v, seen_at=0.0):
    return NeighborPrediction.constant_velocity(3, "perception", seen_at, np.asarray(p, float), np.asarray(v, float), np.zeros((6, 6)))


def test_distance_is_the_exact_capsule_distance_near_it_and_untouched_far_away():
    snap = _empty()
    nb = _nb([0.0, 0.0, 1.5], [1.0, 0.0, 0.0])  # sweeps x from 0 to 1 m over the 1 s horizon
    out = with_neighbour_capsules(snap, [nb], 0.0, 1.0, 0.7, reach_m=1.0)
    centres = snap.index_to_world(np.argwhere(np.ones(snap.shape, bool)))
    d = out.distance_m.reshape(-1)
    seg = np.clip(centres[:, 0], 0.0, 1.0)
    exact = np.linalg.norm(centres - np.c_[seg, np.zeros_like(seg), np.full_like(seg, 1.5)], axis=1) - 0.7
    near = exact <= 1.0
    np.testing.assert_allclose(d[near], np.minimum(exact[near], 3.0), atol=1e-5)
    np.testing.assert_array_equal(d[~near], 3.0)  # beyond reach the map's own distance stands
    assert np.all(snap.distance_m == 3.0)  # the input snapshot is not modified
    assert out.state is snap.state and out.free_distance_m is snap.free_distance_m


def test_a_track_unseen_for_longer_than_t_hold_is_inflated_by_1_2():
    snap = _empty()
    seen = with_neighbour_capsules(snap, [_nb([0.0, 0.0, 1.5], [0.0, 0.0, 0.0], seen_at=0.5)], 1.0, 0.0, 0.7)
    unseen = with_neighbour_capsules(snap, [_nb([0.0, 0.0, 1.5], [0.0, 0.0, 0.0], seen_at=0.2)], 1.0, 0.0, 0.7)
    probe = np.array([[0.9, 0.0, 1.5]])
    idx = tuple(snap.world_to_index(probe)[0])
    centre_dist = np.linalg.norm(snap.index_to_world(np.array([idx]))[0] - [0.0, 0.0, 1.5])
    assert seen.distance_m[idx] == pytest.approx(centre_dist - 0.7, abs=1e-5)
    assert unseen.distance_m[idx] == pytest.approx(centre_dist - 0.84, abs=1e-5)


def test_no_neighbours_returns_the_snapshot_itself_and_a_capsule_outside_the_window_changes_nothing():
    snap = _empty()
    assert with_neighbour_capsules(snap, [], 0.0, 1.0, 0.7) is snap
    out = with_neighbour_capsules(snap, [_nb([50.0, 0.0, 1.5], [0.0, 0.0, 0.0])], 0.0, 1.0, 0.7)
    np.testing.assert_array_equal(out.distance_m, snap.distance_m)


@pytest.mark.parametrize("kw", [{"horizon_s": -1.0}, {"clearance_m": 0.0}, {"unseen_scale": 0.9}, {"reach_m": -0.1}])
def test_invalid_arguments_name_the_field(kw):
    args = {"horizon_s": 1.0, "clearance_m": 0.7}
    args.update(kw)
    field = next(iter(kw))
    with pytest.raises(ValueError, match=f"^{field}="):
        with_neighbour_capsules(_empty(), [_nb([0.0, 0.0, 1.5], [0.0, 0.0, 0.0])], 0.0, **args)


def test_compiled_capsule_equals_its_numpy_reference_to_the_bit():
    from planners.neighbour_field import _capsule_block, capsule_block_numpy

    rng = np.random.default_rng(1)
    shape = np.array([40, 40, 20])
    for trial in range(40):
        dist = rng.uniform(-1, 3, shape).astype(np.float32)
        origin = rng.uniform(-5, 5, 3)
        a = origin + rng.uniform(0, 6, 3) * [1, 1, 0.5]
        b = a.copy() if trial % 5 == 0 else a + rng.normal(0, 1, 3)  # a hovering neighbour: a point capsule
        lo = np.clip(np.floor((np.minimum(a, b) - 2.0 - origin) / 0.15).astype(int), 0, shape)
        hi = np.clip(np.ceil((np.maximum(a, b) + 2.0 - origin) / 0.15).astype(int) + 1, 0, shape)
        ref, new = dist.copy(), dist.copy()
        capsule_block_numpy(ref, origin, 0.15, lo, hi, a, b, 0.7, 1.3)
        _capsule_block(new, origin, 0.15, lo, hi, a, b - a, max(float((b - a) @ (b - a)), 1e-12), 0.7, 1.3)
        np.testing.assert_array_equal(new, ref)
        # a shorter reach cut: more voxels sit near the write decision
        probe_ref, probe_new = dist.copy(), dist.copy()
        capsule_block_numpy(probe_ref, origin, 0.15, lo, hi, a, b, 0.7, 0.5)
        _capsule_block(probe_new, origin, 0.15, lo, hi, a, b - a, max(float((b - a) @ (b - a)), 1e-12), 0.7, 0.5)
        np.testing.assert_array_equal(probe_new, probe_ref)
