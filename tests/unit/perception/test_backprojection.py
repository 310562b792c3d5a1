"""Back-projection (MP-CDE Eq. 7-8): geometry round trip, robust box depth, NaN skip, covariance shape."""

import numpy as np
import pytest

from perception.backprojection import (
    BackprojectionConfig,
    backproject,
    box_depth_m,
    measurement_from_pixel,
    pose_noise_cov,
    ray_covariance,
)
from perception.tracker import Measurement
from perception.types import Detection
from sim.bullet.scene import SceneSpec
from sim.camera import CameraConfig, apply_depth_sensor_model, intrinsics
from sim.rendering.camera_rig import CameraRig
from sim.rendering.tiny import SceneRenderer
from sim.rotations import quat_xyzw_from_yaw, rotation_from_quat_xyzw
from sim.types import ObstacleSpec, RgbdFrame

K = intrinsics(CameraConfig())


def _with(**constants: float) -> BackprojectionConfig:
    """BackprojectionConfig with other values of its class constants (a subclass sets them)."""
    return type("Constants", (BackprojectionConfig,), constants)()


def _pose(yaw: float, pitch: float, pos) -> np.ndarray:
    """A camera pose: optical axis along body x, body yawed and pitched."""
    rig = CameraRig(CameraConfig(), seed=0)
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    R = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1.0]]) @ np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    return rig.transform_camera_to_world(np.asarray(pos, float), R)


@pytest.mark.parametrize("u,v,d", [(10.0, 20.0, 0.7), (159.5, 119.5, 3.0), (301.3, 200.8, 9.4)])
def test_pixel_to_world_to_pixel_round_trip(u, v, d):
    T = _pose(0.7, -0.2, [1.0, -2.0, 1.5])
    cfg = _with(surface_to_centre_m=0.0)
    m = measurement_from_pixel(u, v, d, 9, 10.0, K, T, 1.25, cfg)
    assert isinstance(m, Measurement) and m.time_s == 1.25
    p_c = np.linalg.inv(T) @ np.append(m.pos_world, 1.0)
    assert p_c[2] == pytest.approx(d, abs=1e-9)  # depth is along the optical axis
    uv = (K @ (p_c[:3] / p_c[2]))[:2]
    assert uv == pytest.approx([u, v], abs=1e-9)


def test_surface_to_centre_offset_moves_the_point_along_the_ray():
    T = _pose(-1.1, 0.1, [0.0, 0.0, 2.0])
    a = measurement_from_pixel(50.0, 60.0, 4.0, 9, 10.0, K, T, 0.0, _with(surface_to_centre_m=0.0))
    b = measurement_from_pixel(50.0, 60.0, 4.0, 9, 10.0, K, T, 0.0, _with(surface_to_centre_m=0.05))
    ray_w = a.pos_world - T[:3, 3]
    assert np.linalg.norm(b.pos_world - a.pos_world) == pytest.approx(0.05)
    assert np.cross(b.pos_world - a.pos_world, ray_w) == pytest.approx(np.zeros(3), abs=1e-12)


def test_covariance_is_long_along_the_ray_and_grows_with_range():
    T = _pose(0.3, 0.0, [0.0, 0.0, 1.0])
    near = measurement_from_pixel(200.0, 90.0, 2.0, 9, 20.0, K, T, 0.0)
    far = measurement_from_pixel(200.0, 90.0, 8.0, 9, 5.0, K, T, 0.0)
    for m in (near, far):
        w, V = np.linalg.eigh(m.cov_world)
        assert np.all(w > 0) and m.cov_world == pytest.approx(m.cov_world.T)
        ray = (m.pos_world - T[:3, 3]) / np.linalg.norm(m.pos_world - T[:3, 3])
        assert abs(V[:, -1] @ ray) == pytest.approx(1.0, abs=1e-6)  # largest axis along the ray
    w_far = np.linalg.eigvalsh(far.cov_world)
    assert w_far[-1] > 2.0 * w_far[0]  # far away the depth noise (q z^2) dominates
    assert np.trace(far.cov_world) > 4.0 * np.trace(near.cov_world)


def test_box_half_over_background_still_gets_the_drone_depth(rng):
    depth = np.full((240, 320), 8.0, np.float32)
    depth[100:120, 140:160] = 3.0  # drone: left half of the box [139.5, 179.5] x [99.5, 119.5]
    depth += (0.002 + 0.0025 * depth**2) * rng.standard_normal(depth.shape).astype(np.float32)
    d, n = box_depth_m(depth, np.array([139.5, 99.5, 179.5, 119.5]))
    assert d == pytest.approx(3.0, abs=0.03) and n >= 9
    # a drone seen as a ring (arms, rotors) with the background at the box centre itself
    ring = np.full((240, 320), 8.0, np.float32)
    ring[90:130, 140:180] = 2.0
    ring[107:113, 157:163] = 8.0  # the central 3x3 of MP-CDE would read 8 m here
    d, _ = box_depth_m(ring, np.array([139.5, 89.5, 179.5, 129.5]))
    assert d == pytest.approx(2.0)


def test_boxes_without_valid_depth_are_skipped_and_reported():
    depth = np.full((240, 320), 5.0, np.float32)
    depth[:, :100] = np.nan  # sky / out of range
    frame = RgbdFrame(drone_id=0, time_s=2.0, rgb=np.zeros((240, 320, 3), np.uint8), depth_m=depth, K=K, transform_camera_to_world=np.eye(4))
    dets = [Detection(np.array([10.0, 10.0, 40.0, 30.0]), 0.9), Detection(np.array([200.0, 100.0, 220.0, 112.0]), 0.8)]
    result = backproject(frame, dets)
    assert list(result.skipped) == [0] and list(result.detection_index) == [1]
    ray = np.linalg.solve(K, [210.0, 106.0, 1.0])  # the box centre
    assert len(result.measurements) == 1
    assert np.linalg.norm(result.measurements[0].pos_world) == pytest.approx(5.0 * np.linalg.norm(ray) + 0.03)


def test_rendered_drones_back_project_to_their_true_centres():
    """Render -> mask boxes -> sensor-noise depth -> Eq. 7-8: error within 5 cm + 1 % of range."""
    wall = ObstacleSpec(kind="box", center_xy=(9.0, 0.0), height_m=4.0, half_extents_xy=(0.2, 6.0))
    pos = np.array([[0.0, 0.0, 1.5], [1.2, 0.3, 1.6], [2.5, -0.6, 1.3], [4.0, 0.8, 1.7], [6.0, -1.5, 1.2]])
    quat = np.stack([quat_xyzw_from_yaw(y) for y in (0.0, 0.5, -1.0, 2.0, 0.8)])
    renderer = SceneRenderer(SceneSpec(obstacles=(wall,), n_drones=5), CameraConfig())
    try:
        renderer.set_drone_poses(pos, quat)
        T = CameraRig(CameraConfig(), seed=0).transform_camera_to_world(pos[0], rotation_from_quat_xyzw(quat[0]))
        raw = renderer.render(T, own_drone=0)
    finally:
        renderer.close()
    depth = apply_depth_sensor_model(raw.depth_true_m, np.random.default_rng(3), CameraConfig())
    frame = RgbdFrame(drone_id=0, time_s=0.0, rgb=raw.rgb, depth_m=depth, K=K, transform_camera_to_world=T)
    dets = []
    for i in range(1, 5):
        vs, us = np.nonzero(raw.drone_index_mask == i)
        dets.append(Detection(np.array([us.min() - 0.5, vs.min() - 0.5, us.max() + 0.5, vs.max() + 0.5]), 1.0))
    result = backproject(frame, dets)
    assert result.skipped.size == 0
    for m, i in zip(result.measurements, range(1, 5)):
        range_m = np.linalg.norm(pos[i] - T[:3, 3])
        assert np.linalg.norm(m.pos_world - pos[i]) < 0.05 + 0.01 * range_m, f"drone {i} at {range_m:.1f} m"


def test_pose_noise_covariance_matches_sampled_pose_errors(rng):
    """Position noise moves the point, heading noise swings it about the vertical through the camera."""
    offset = np.array([4.0, -1.5, 0.7])
    pos_std, yaw_std = 0.02, 0.01
    n = 200_000
    dyaw = yaw_std * rng.standard_normal(n)
    c, s = np.cos(dyaw), np.sin(dyaw)
    swung = np.stack([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1], np.full(n, offset[2])], axis=1)
    samples = swung + pos_std * rng.standard_normal((n, 3))
    np.testing.assert_allclose(np.cov(samples.T), pose_noise_cov(offset, pos_std, yaw_std), atol=3e-5)


def test_ray_covariance_has_the_given_std_along_and_across_the_ray():
    e = np.array([2.0, 1.0, -2.0]) / 3.0
    cov = ray_covariance(e, 0.05, 0.01)
    assert e @ cov @ e == pytest.approx(0.05**2)
    across = np.cross(e, [0.0, 0.0, 1.0])
    across /= np.linalg.norm(across)
    assert across @ cov @ across == pytest.approx(0.01**2)
    assert np.trace(cov) == pytest.approx(0.05**2 + 2 * 0.01**2)


def test_compiled_box_depth_equals_its_numpy_reference_to_the_bit():
    """percentile ('lower'), the foreground band and the median, with holes, ties, empty and clipped windows."""
    from perception.backprojection import box_depth_m, box_depth_numpy
    from perception.backprojection_config import BackprojectionConfig

    rng = np.random.default_rng(4)
    at = {p: _with(foreground_percentile=p) for p in (0.0, 20.0, 33.3, 50.0)}  # a class constant
    for t in range(400):
        d = rng.uniform(0.3, 12, (60, 80)).astype(np.float32)
        if t % 3 == 0:
            d[rng.random(d.shape) < 0.3] = np.nan
        if t % 11 == 0:
            d[:] = np.nan
        if t % 5 == 0:
            d = np.round(d, 1).astype(np.float32)  # repeated depths
        x0, y0 = rng.uniform(-10, 80), rng.uniform(-10, 60)
        box = np.array([x0, y0, x0 + rng.uniform(0, 40), y0 + rng.uniform(0, 30)])
        cfg = at[float(rng.choice([0.0, 20.0, 33.3, 50.0]))]
        got, ref = box_depth_m(d, box, cfg), box_depth_numpy(d, box, cfg)
        assert got[1] == ref[1]
        assert got[0] == ref[0] or (np.isnan(got[0]) and np.isnan(ref[0]))
