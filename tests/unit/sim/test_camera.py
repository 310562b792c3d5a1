"""Camera geometry: depth conversion, projection of drones onto their masks, back-projection."""

import numpy as np
import pytest

from sim.bullet.scene import SceneSpec
from sim.camera import CameraConfig, apply_depth_sensor_model, depth_buffer_to_depth_m, intrinsics
from sim.rendering.camera_rig import CameraRig
from sim.rendering.tiny import SceneRenderer
from sim.rotations import quat_xyzw_from_yaw, rotation_from_quat_xyzw
from sim.types import ObstacleSpec


def test_depth_buffer_conversion_inverts_the_opengl_z_mapping():
    near, far = 0.05, 30.0
    z = np.array([0.05, 0.2, 1.0, 3.3, 9.99, 30.0])
    # OpenGL: z_ndc = (f + n)/(f - n) - 2 f n / ((f - n) z); d = (z_ndc + 1) / 2
    d = ((far + near) / (far - near) - 2 * far * near / ((far - near) * z) + 1) / 2
    assert depth_buffer_to_depth_m(d, near, far) == pytest.approx(z, rel=1e-6)


def test_intrinsics_give_the_d435i_field_of_view():
    cfg = CameraConfig()
    K = intrinsics(cfg)
    hfov = 2 * np.degrees(np.arctan((cfg.width_px / 2) / K[0, 0]))
    vfov = 2 * np.degrees(np.arctan((cfg.height_px / 2) / K[1, 1]))
    assert (hfov, vfov) == pytest.approx((85.0, 58.0))


def test_depth_model_marks_out_of_range_invalid_and_noise_grows_with_range(rng):
    cfg = CameraConfig()
    z = np.concatenate([np.full(20000, 1.0), np.full(20000, 6.0), [0.1, 12.0, np.inf]]).astype(np.float32)
    d = apply_depth_sensor_model(z.reshape(1, -1), rng, cfg)[0]
    assert np.all(np.isnan(d[-3:]))
    s1, s6 = np.std(d[:20000] - 1.0), np.std(d[20000:40000] - 6.0)
    assert s1 == pytest.approx(cfg.depth_noise_base_m + cfg.depth_noise_quadratic_per_m * 1.0, rel=0.05)
    assert s6 == pytest.approx(cfg.depth_noise_base_m + cfg.depth_noise_quadratic_per_m * 36.0, rel=0.05)


@pytest.fixture(scope="module")
def drone_scene():
    """A camera drone at the origin looking along +x at three drones; a wall behind them."""
    wall = ObstacleSpec(kind="box", center_xy=(9.0, 0.0), height_m=4.0, half_extents_xy=(0.2, 6.0))
    spec = SceneSpec(obstacles=(wall,), n_drones=4)
    pos = np.array([[0.0, 0.0, 1.5], [2.0, 0.4, 1.6], [4.0, -1.2, 1.2], [6.5, -3.0, 1.9]])
    quat = np.stack([quat_xyzw_from_yaw(y) for y in (0.0, 0.3, -1.0, 2.0)])
    renderer = SceneRenderer(spec, CameraConfig())
    renderer.set_drone_poses(pos, quat)
    rig = CameraRig(CameraConfig(), seed=0)
    T_cw = rig.transform_camera_to_world(pos[0], rotation_from_quat_xyzw(quat[0]))
    raw = renderer.render(T_cw, own_drone=0)
    yield pos, T_cw, raw, rig.K
    renderer.close()


def test_each_drone_projects_to_the_centroid_of_its_mask_within_2_px(drone_scene):
    pos, T_cw, raw, K = drone_scene
    T_wc = np.linalg.inv(T_cw)
    for i in (1, 2, 3):
        vs, us = np.nonzero(raw.drone_index_mask == i)
        assert us.size >= 5, f"drone {i} not visible"
        p_c = T_wc[:3, :3] @ pos[i] + T_wc[:3, 3]
        uv = (K @ (p_c / p_c[2]))[:2]
        assert np.hypot(us.mean() - uv[0], vs.mean() - uv[1]) < 2.0, f"drone {i}"
    assert not np.any(raw.drone_index_mask == 0), "a camera must not see its own drone"


def test_back_projecting_the_mask_centroid_with_rendered_depth_recovers_the_position(drone_scene):
    pos, T_cw, raw, K = drone_scene
    K_inv = np.linalg.inv(K)
    for i in (1, 2, 3):
        vs, us = np.nonzero(raw.drone_index_mask == i)
        u, v = int(round(us.mean())), int(round(vs.mean()))
        window = raw.depth_true_m[v - 1 : v + 2, u - 1 : u + 2]
        d = float(np.median(window[raw.drone_index_mask[v - 1 : v + 2, u - 1 : u + 2] == i]))
        p_c = d * K_inv @ np.array([u, v, 1.0])  # MP-CDE Eq. 7
        p_w = T_cw[:3, :3] @ p_c + T_cw[:3, 3]  # MP-CDE Eq. 8
        rng_m = np.linalg.norm(pos[i] - T_cw[:3, 3])
        assert np.linalg.norm(p_w - pos[i]) < 0.05 + 0.02 * rng_m, f"drone {i} at {rng_m:.1f} m"


def test_rendered_depth_of_a_wall_is_its_distance_along_the_optical_axis(drone_scene):
    _, T_cw, raw, _ = drone_scene
    # the wall's front face is the plane x = 8.8 m; depth along the optical axis (world +x) is 8.8 - x_cam
    col = raw.depth_true_m[:, 60]  # a column through the wall where no drone is
    rows = np.isfinite(col) & (col > 8.0) & (col < 9.5) & (np.arange(col.size) < col.size // 2)  # above the horizon: no ground
    assert rows.sum() > 10
    err = np.abs(col[rows] - (8.8 - T_cw[0, 3]))
    assert err.max() < 2e-3, f"max error {err.max():.4f} m"


def test_rendered_silhouette_edges_sit_where_the_intrinsics_project_them():
    """Pixel convention: pixel (u, v) of a render is the OpenCV pixel centred at (u, v) of K.

    A pixel is covered when its centre is inside the projected silhouette, so
    the first covered column lies within [0, 1) px right of the projected left
    edge, the last within [0, 1) px left of the right edge, and the first
    covered row within [0, 1) px below the top edge. A half-pixel shift of the
    render (the former ``c_gl = c + 0.5``) puts these at [0.5, 1.5) or
    [-0.5, 0.5) and fails.
    """
    cfg = CameraConfig()
    rig = CameraRig(cfg, seed=0)
    T_cw = rig.transform_camera_to_world(np.array([0.0, 0.0, 1.5]), np.eye(3))
    T_wc = np.linalg.inv(T_cw)

    def project(points_world):
        p_c = points_world @ T_wc[:3, :3].T + T_wc[:3, 3]
        return (p_c[:, :2] / p_c[:, 2:]) * np.diag(rig.K)[:2] + rig.K[:2, 2]

    gaps = []
    for x_m, y_m, top_m in ((2.5, -0.7, 1.6), (3.0, 0.0, 1.83), (4.1, 0.41, 2.1), (5.0, 0.9, 2.37), (6.3, -0.33, 1.7)):
        post = ObstacleSpec(kind="box", center_xy=(x_m, y_m), height_m=5.0, half_extents_xy=(0.05, 0.3))
        beam = ObstacleSpec(kind="box", center_xy=(x_m, 0.0), height_m=top_m, half_extents_xy=(0.05, 2.0))
        for box, corners in (
            (post, np.array([[x_m + sx * 0.05, y_m + sy * 0.3, 1.5] for sx in (-1, 1) for sy in (-1, 1)])),
            (beam, np.array([[x_m + sx * 0.05, 0.0, top_m] for sx in (-1, 1)])),
        ):
            renderer = SceneRenderer(SceneSpec(obstacles=(box,), n_drones=1), cfg)
            renderer.set_drone_poses(np.array([[0.0, 0.0, 1.5]]), quat_xyzw_from_yaw(0.0)[None])
            depth = renderer.render(T_cw, own_drone=0).depth_true_m
            renderer.close()
            uv = project(corners)
            if box is post:
                us = np.nonzero(depth[cfg.height_px // 2] < x_m + 1.0)[0]
                gaps += [us.min() - uv[:, 0].min(), uv[:, 0].max() - us.max()]
            else:
                vs = np.nonzero(depth[:, cfg.width_px // 2] < x_m + 1.0)[0]
                gaps.append(vs.min() - uv[:, 1].min())
    gaps = np.array(gaps)
    assert np.all((gaps > -0.02) & (gaps < 1.02)), np.round(gaps, 2)


def test_a_render_leaves_every_drone_where_it_was_set_bit_for_bit():
    """Hiding the own drone and putting it back must not move it by a rounding error.

    PyBullet's get/reset round trip of a base pose is not exact (it goes through
    the centre-of-mass frame); restoring from it made a render depend on which
    cameras the client had rendered before, hence flights on the worker count.
    """
    from sim.bullet import pb

    rng = np.random.default_rng(4)
    n = 4
    renderer = SceneRenderer(SceneSpec(obstacles=(), n_drones=n), CameraConfig(width_px=32, height_px=24))
    rig = CameraRig(CameraConfig(width_px=32, height_px=24), seed=0)
    try:
        for _ in range(10):
            pos = rng.normal(0.0, 2.0, (n, 3)) + [0.0, 0.0, 2.0]
            quat = rng.normal(size=(n, 4))
            quat /= np.linalg.norm(quat, axis=1, keepdims=True)
            renderer.set_drone_poses(pos, quat)
            placed = [pb.getBasePositionAndOrientation(b, physicsClientId=renderer.client) for b in renderer.drone_ids]
            for i in range(n):
                renderer.render(rig.transform_camera_to_world(pos[i], rotation_from_quat_xyzw(quat[i])), own_drone=i)
            after = [pb.getBasePositionAndOrientation(b, physicsClientId=renderer.client) for b in renderer.drone_ids]
            assert after == placed
    finally:
        renderer.close()


def test_compose_equals_the_buffer_conversions_it_fuses():
    """The renderer's one-pass composition gives what the separate conversions give (depth formula, mask LUT, ground/sky)."""
    from sim.camera import depth_buffer_to_depth_m
    from sim.rendering.tiny import _compose

    rng = np.random.default_rng(2)
    H, W = 24, 32
    rgba = rng.integers(0, 256, (H, W, 4), dtype=np.uint8)
    zbuf = rng.uniform(0.0, 1.0, (H, W)).astype(np.float32)
    seg = rng.integers(-1, 5, (H, W)).astype(np.int32)
    lut = np.array([-1, -1, 0, 1, -1], np.int16)  # body 3 would fall off the end: clipped like np.take(mode="clip")
    ray_x = np.linspace(-0.9, 0.9, W).astype(np.float32)
    ray_y = np.linspace(-0.5, 0.5, H).astype(np.float32)
    R = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]) @ np.array(
        [[1, 0, 0], [0, np.cos(0.3), -np.sin(0.3)], [0, np.sin(0.3), np.cos(0.3)]]
    )
    t = np.array([0.3, -0.2, 1.5])
    tiles = (np.array([100, 120, 90], np.uint8), np.array([80, 100, 70], np.uint8), np.array([170, 200, 230], np.uint8))
    rgb, depth, mask = _compose(rgba, zbuf, seg, lut, 0.05, 30.0, ray_x, ray_y, R, t, *tiles)
    fg = seg >= 0
    np.testing.assert_array_equal(rgb[fg], rgba[..., :3][fg])
    np.testing.assert_array_equal(depth[fg], depth_buffer_to_depth_m(zbuf, 0.05, 30.0)[fg])
    np.testing.assert_array_equal(mask, np.take(lut, seg + 1, mode="clip"))
    # background: the ground z = 0 where the pixel ray descends within the far plane, else the sky at inf
    d = (R @ np.stack(np.broadcast_arrays(ray_x[None, :], ray_y[:, None], np.ones((H, W))), 0).reshape(3, -1)).reshape(3, H, W)
    lam = np.where(d[2] < -1e-9, -t[2] / np.where(d[2] < -1e-9, d[2], -1.0), np.inf)
    ground = ~fg & (lam <= 30.0)
    np.testing.assert_allclose(depth[ground], lam[ground], rtol=1e-6)
    assert np.all(np.isinf(depth[~fg & ~ground])) and np.all(rgb[~fg & ~ground] == tiles[2])
