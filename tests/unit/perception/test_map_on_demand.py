"""The map's deferred ESDF, the per-frame clearance without a transform, and the traversal stride."""

from __future__ import annotations

import numpy as np
import pytest

from perception.esdf import signed_distance
from perception.map_config import MapConfig
from perception.occupancy_map import OccupancyMap
from perception.types import OccupancySnapshot
from test_occupancy_map import CAM_POS, X_WALL, camera_pose, cylinder_depth, intrinsics, make_frame, wall_depth, wall_scene  # noqa: F401 (fixture)


def test_frames_cost_no_transform_until_a_planner_reads_the_esdf(wall_scene) -> None:
    K, T, depth = wall_scene
    m = OccupancyMap()
    for k in range(3):
        m.update(make_frame(K, T, depth, 0.04 * k))
        snap = m.snapshot()
    assert m.esdf_count == 0 and not snap.distance_ready
    d = snap.distance_m
    assert m.esdf_count == 1 and snap.distance_ready and not d.flags.writeable
    assert snap.distance_m is d  # computed once
    expected = signed_distance(snap.state == OccupancySnapshot.OCCUPIED, m.config.voxel_m, m.config.esdf_max_m)
    np.testing.assert_array_equal(d, expected)
    snap.free_distance_m
    assert m.esdf_count == 2


def test_snapshot_cannot_be_changed(wall_scene) -> None:
    K, T, depth = wall_scene
    m = OccupancyMap()
    m.update(make_frame(K, T, depth))
    snap = m.snapshot()
    with pytest.raises(AttributeError):
        snap.time_s = 3.0
    with pytest.raises(ValueError):
        snap.distance_m[0, 0, 0] = 1.0


def test_a_deferred_layer_of_the_wrong_shape_is_refused() -> None:
    state = np.zeros((4, 4, 4), np.int8)
    snap = OccupancySnapshot(0.0, np.zeros(3), 0.15, state, lambda: np.zeros((3, 3, 3)), np.zeros((4, 4, 4)))
    with pytest.raises(ValueError, match="distance_m shape"):
        snap.distance_m


def test_clearance_equals_the_fresh_esdf_when_nothing_new_is_occupied(wall_scene) -> None:
    K, T, depth = wall_scene
    m = OccupancyMap()
    m.update(make_frame(K, T, depth))
    pts = np.random.default_rng(0).uniform(CAM_POS - [1.0, 2.0, 1.0], CAM_POS + [3.5, 2.0, 1.0], (200, 3))
    fresh, _ = m.snapshot().distance_and_gradient(pts)
    np.testing.assert_allclose(m.clearance(pts), fresh, atol=1e-6)
    m.update(make_frame(K, T, depth, 0.04))  # the same wall again: nothing new becomes occupied
    count = m.esdf_count
    np.testing.assert_allclose(m.clearance(pts), fresh, atol=1e-6)
    assert m.esdf_count == count


def test_clearance_sees_an_obstacle_that_appeared_after_the_last_esdf(wall_scene) -> None:
    K, T, depth = wall_scene
    m = OccupancyMap()
    m.update(make_frame(K, T, depth))
    m.snapshot().distance_m  # the ESDF clearance() starts from: only the wall
    tree = np.array([1.6, 0.2])
    both = np.fmin(depth, cylinder_depth(K, T, tree, 0.2))
    for k in range(1, 3):
        m.update(make_frame(K, T, both, 0.04 * k))
    count = m.esdf_count
    # points in front of the tree, between it and the camera
    pts = np.array([[tree[0] - r, tree[1], 1.5] for r in (0.3, 0.45, 0.6, 0.9)])
    cheap = m.clearance(pts)
    assert m.esdf_count == count  # no transform
    fresh, _ = m.snapshot().distance_and_gradient(pts)
    old = signed_distance(np.zeros(m.snapshot().shape, bool), 0.15, 3.0)  # sanity: the tree is far from the wall
    assert np.all(fresh < 1.0) and old.min() > 1.0
    # within the interpolation error of the field (about half a voxel), never above it by more
    assert np.all(np.abs(cheap - fresh) <= 0.5 * m.config.voxel_m + 1e-6)


@pytest.mark.parametrize("yaw", [0.2, -0.4])
def test_clear_stride_keeps_every_hit_and_clears_almost_all_free_space(yaw) -> None:
    K = intrinsics()
    T = camera_pose(CAM_POS, yaw)
    depth = np.fmin(wall_depth(K, T, X_WALL, 2.5, (0.3, 2.7)), cylinder_depth(K, T, np.array([1.5, 0.3]), 0.25))
    every = OccupancyMap(type("ClearEveryRay", (MapConfig,), {"clear_stride": 2})())  # every ray traversed (a class constant)
    sparse = OccupancyMap(MapConfig())  # default: every 4th pixel traversed
    for k in range(2):
        every.update(make_frame(K, T, depth, 0.04 * k))
        sparse.update(make_frame(K, T, depth, 0.04 * k))
    a, b = every.state(), sparse.state()
    assert np.array_equal(a == 1, b == 1)  # the same occupied voxels
    assert not np.any((a == -1) & (b != -1))  # nothing seen that the full traversal did not see
    free_a, free_b = (a == 0).sum(), (b == 0).sum()
    assert free_b >= 0.95 * free_a  # the rest are grazed voxels that moving frames fill (docs/results/realtime.md#the-map-the-esdf-and-the-planners)


def test_clear_stride_is_validated() -> None:
    with pytest.raises(ValueError, match="^clear_stride="):
        type("NoStride", (MapConfig,), {"clear_stride": 0})()  # a class constant: a subclass overrides it


@pytest.mark.parametrize("dets", [(), ((100.0, 60.0, 180.0, 120.0),), ((0.0, 0.0, 40.0, 30.0), (250.0, 150.0, 319.0, 239.0))])
def test_compiled_rays_equal_the_numpy_reference(dets) -> None:
    from perception.ray_integration import rays_camera_numpy
    from perception.types import Detection

    K = intrinsics()
    T = camera_pose(CAM_POS, 0.3)
    depth = np.fmin(wall_depth(K, T, X_WALL, 2.5, (0.3, 2.7)), cylinder_depth(K, T, np.array([1.5, 0.3]), 0.25))
    rng = np.random.default_rng(3)
    depth[rng.random(depth.shape) < 0.05] = np.nan  # stereo holes
    depth[:5, :5] = 25.0  # beyond the range
    depth[200:202, 10:12] = 0.1  # nearer than the minimum
    frame = make_frame(K, T, depth)
    detections = [Detection(box_xyxy=np.array(b), score=0.9) for b in dets]
    m = OccupancyMap()
    got = m._rays_camera(frame, detections)
    ref = rays_camera_numpy(m.config, frame, detections)
    assert got[0].shape == ref[0].shape
    np.testing.assert_allclose(got[0], ref[0], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(got[1], ref[1])
    np.testing.assert_allclose(got[2], ref[2], rtol=0, atol=1e-12)


def test_compiled_clearance_equals_its_numpy_reference_to_the_bit() -> None:
    from perception.occupancy_map import _clearance, clearance_numpy

    rng = np.random.default_rng(2)
    for trial in range(60):
        dist = rng.uniform(-3, 3, (30, 28, 12)).astype(np.float32)
        origin, v = rng.uniform(-10, 10, 3), 0.15
        p = origin + rng.uniform(-1, 6, (40, 3)) * [1, 1, 0.4]  # some outside the window: clamped
        centres = (rng.integers(-5, 35, (int(rng.integers(0, 50)) if trial % 3 else 0, 3)) + 0.5) * v + origin
        np.testing.assert_array_equal(_clearance(dist, origin, v, p, centres), clearance_numpy(dist, origin, v, p, centres))
    p = np.array([[np.nan, 0.0, 1.0], [0.0, np.inf, 1.0], [0.5, 0.5, 0.5]]) + origin
    got = _clearance(dist, origin, v, p, np.empty((0, 3)))
    assert np.isnan(got[0]) and np.isnan(got[1]) and got[2] == clearance_numpy(dist, origin, v, p[2:], np.empty((0, 3)))[0]
