"""The analytic renderer against TinyRenderer: the same depth (up to tessellation), masks and layout of colours."""

from __future__ import annotations

import numpy as np
import pytest

from sim.bullet.scene import DRONE_URDF, SceneSpec
from sim.camera import CameraConfig
from sim.rendering.camera_rig import CameraRig
from sim.rendering.raycast import BOX, CYLINDER, RaycastRenderer, drone_primitives
from sim.rendering.tiny import SceneRenderer
from sim.rotations import quat_xyzw_from_yaw, rotation_from_quat_xyzw
from sim.types import ObstacleSpec

OBSTACLES = (
    ObstacleSpec("tree", (3.0, 0.4), 4.0, radius_m=0.25),
    ObstacleSpec("tree", (5.5, -1.6), 3.0, radius_m=0.35, rgba=(0.3, 0.5, 0.25, 1.0)),
    ObstacleSpec("box", (4.0, 2.0), 1.2, half_extents_xy=(0.4, 0.7), yaw=0.5, rgba=(0.6, 0.6, 0.65, 1.0)),
    ObstacleSpec("tree", (-2.0, 0.0), 4.0, radius_m=0.3),  # behind the cameras
)
POS = np.array([[0.0, 0.0, 1.5], [1.2, 0.15, 1.45], [2.0, -0.5, 1.7], [2.6, 1.0, 1.3]])
YAW = np.array([0.05, 0.7, -0.4, 2.0])


@pytest.fixture(scope="module")
def renders() -> list[tuple]:
    cam = CameraConfig()
    spec = SceneSpec(obstacles=OBSTACLES, n_drones=len(POS))
    quat = np.stack([quat_xyzw_from_yaw(y) for y in YAW])
    rig = CameraRig(cam, 0)
    R = rotation_from_quat_xyzw(quat)
    tiny, ray = SceneRenderer(spec, cam), RaycastRenderer(spec, cam)
    out = []
    for r in (tiny, ray):
        r.set_drone_poses(POS, quat)
    for i in range(2):
        T = rig.transform_camera_to_world(POS[i], R[i])
        out.append((tiny.render(T, i), ray.render(T, i)))
    tiny.close()
    return out


def test_the_urdf_visuals_become_boxes_and_cylinders() -> None:
    kind, centre, rot, size, rgb = drone_primitives(DRONE_URDF)
    assert len(kind) == 14 and set(kind.tolist()) == {BOX, CYLINDER}
    assert np.allclose(size[0], [0.055, 0.03, 0.0175])  # the body box, half of 0.11 x 0.06 x 0.035
    assert np.allclose(rot @ rot.transpose(0, 2, 1), np.eye(3))
    assert np.all((rgb >= 0) & (rgb <= 1))


def test_depth_agrees_with_tinyrenderer_up_to_tessellation(renders) -> None:
    for tiny, ray in renders:
        a, b = tiny.depth_true_m, ray.depth_true_m
        assert np.mean(np.isfinite(a) == np.isfinite(b)) > 0.995
        both = np.isfinite(a) & np.isfinite(b) & (a < 10.0)
        err = np.abs(a[both] - b[both])
        assert np.median(err) < 1e-3 and np.percentile(err, 99) < 0.03  # TinyRenderer's cylinders are polygons


def test_drone_masks_agree_with_tinyrenderer(renders) -> None:
    seen = 0
    for tiny, ray in renders:
        for k in range(len(POS)):
            a, b = tiny.drone_index_mask == k, ray.drone_index_mask == k
            if a.sum() < 20:
                continue
            seen += 1
            assert (a & b).sum() / (a | b).sum() > 0.85
    assert seen >= 2
    assert np.all(renders[0][1].drone_index_mask != 0)  # a camera never sees its own drone


def test_colours_are_close_to_tinyrenderer(renders) -> None:
    for tiny, ray in renders:
        diff = np.abs(tiny.rgb.astype(int) - ray.rgb.astype(int))
        assert diff.mean() < 4.0  # same materials and light; the shading model differs (module docstring)


def test_the_renderer_is_chosen_by_the_camera_config() -> None:
    from sim.rendering.pool import make_renderer

    spec = SceneSpec(obstacles=OBSTACLES[:1], n_drones=1)
    assert isinstance(make_renderer(spec, CameraConfig()), RaycastRenderer)  # the default
    r = make_renderer(spec, CameraConfig(renderer="tiny"))
    assert isinstance(r, SceneRenderer)
    r.close()
    with pytest.raises(ValueError, match="^renderer="):
        CameraConfig(renderer="opengl")
