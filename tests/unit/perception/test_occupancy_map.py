"""Occupancy map from analytic depth frames: walls become occupied, the space before them free, behind unknown."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from perception.map_config import MapConfig
from perception.occupancy_map import OccupancyMap
from perception.types import Detection
from sim.types import RgbdFrame

W_PX, H_PX = 320, 240
VOXEL_M = 0.15


def intrinsics() -> np.ndarray:
    """K (3, 3) of the default 320 x 240 camera with 85 x 58 deg field of view."""
    fx = (W_PX / 2) / np.tan(np.radians(85 / 2))
    fy = (H_PX / 2) / np.tan(np.radians(58 / 2))
    return np.array([[fx, 0.0, (W_PX - 1) / 2], [0.0, fy, (H_PX - 1) / 2], [0.0, 0.0, 1.0]])


def camera_pose(pos_world: np.ndarray, yaw: float) -> np.ndarray:
    """transform_camera_to_world (4, 4) of a level forward camera at ``pos_world`` (3,) heading ``yaw`` [rad]."""
    fwd = np.array([np.cos(yaw), np.sin(yaw), 0.0])
    left = np.array([-np.sin(yaw), np.cos(yaw), 0.0])
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = -left, -np.array([0.0, 0.0, 1.0]), fwd, pos_world
    return T


def pixel_rays_world(K: np.ndarray, T: np.ndarray) -> np.ndarray:
    """(H, W, 3) world directions R K^-1 [u, v, 1] (unit optical-axis component, so depth = ray parameter)."""
    u, v = np.meshgrid(np.arange(W_PX, dtype=float), np.arange(H_PX, dtype=float))
    rays_cam = np.stack([u, v, np.ones_like(u)], axis=-1) @ np.linalg.inv(K).T
    return rays_cam @ T[:3, :3].T


def wall_depth(K: np.ndarray, T: np.ndarray, x_wall: float, y_half: float, z_lim: tuple[float, float]) -> np.ndarray:
    """Exact depth [m] (H, W) of the wall x = ``x_wall``, |y| <= ``y_half``, z in ``z_lim``; NaN elsewhere."""
    r, o = pixel_rays_world(K, T), T[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = (x_wall - o[0]) / r[..., 0]
    p = o + s[..., None] * r
    hit = (s >= 0.2) & (s <= 10.0) & (np.abs(p[..., 1]) <= y_half) & (p[..., 2] >= z_lim[0]) & (p[..., 2] <= z_lim[1])
    return np.where(hit, s, np.nan).astype(np.float32)


def cylinder_depth(K: np.ndarray, T: np.ndarray, center_xy: np.ndarray, radius_m: float) -> np.ndarray:
    """Exact depth [m] (H, W) of an infinite vertical cylinder; NaN where missed or out of range."""
    r, o = pixel_rays_world(K, T), T[:3, 3]
    dxy, oxy = r[..., :2], o[:2] - center_xy
    a = np.sum(dxy**2, axis=-1)
    b = 2 * np.sum(dxy * oxy, axis=-1)
    c = np.sum(oxy**2) - radius_m**2
    disc = b**2 - 4 * a * c
    with np.errstate(invalid="ignore"):
        s = (-b - np.sqrt(disc)) / (2 * a)  # near intersection
    ok = (disc >= 0) & (s >= 0.2) & (s <= 10.0)
    return np.where(ok, s, np.nan).astype(np.float32)


def make_frame(K: np.ndarray, T: np.ndarray, depth_m: np.ndarray, time_s: float = 0.0) -> RgbdFrame:
    return RgbdFrame(0, time_s, np.zeros((H_PX, W_PX, 3), np.uint8), depth_m, K, T)


def project(K: np.ndarray, T: np.ndarray, points_world: np.ndarray) -> np.ndarray:
    """Pixel coordinates (n, 2) of world points (n, 3)."""
    T_cw = np.linalg.inv(T)
    p_c = points_world @ T_cw[:3, :3].T + T_cw[:3, 3]
    uv = p_c @ K.T
    return uv[:, :2] / uv[:, 2:3]


CAM_POS = np.array([0.2, -0.1, 1.5])
CAM_YAW = 0.2
X_WALL = 3.07  # inside the voxel slab [3.00, 3.15)


@pytest.fixture
def wall_scene() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    K = intrinsics()
    T = camera_pose(CAM_POS, CAM_YAW)
    return K, T, wall_depth(K, T, X_WALL, 2.5, (0.3, 2.7))


def wall_voxel_centres(K: np.ndarray, T: np.ndarray, margin_px: float) -> np.ndarray:
    """Centres (n, 3) of the voxels of the wall slab whose centre is visible ``margin_px`` inside the image."""
    y = (np.arange(-8, 8) + 0.5) * VOXEL_M
    z = (np.arange(3, 17) + 0.5) * VOXEL_M
    yy, zz = np.meshgrid(y, z)
    pts = np.stack([np.full(yy.size, 20.5 * VOXEL_M), yy.ravel(), zz.ravel()], axis=1)
    uv = project(K, T, pts)
    vis = (uv[:, 0] > margin_px) & (uv[:, 0] < W_PX - margin_px) & (uv[:, 1] > margin_px) & (uv[:, 1] < H_PX - margin_px)
    return pts[vis]


def test_wall_voxels_become_occupied(wall_scene) -> None:
    K, T, depth = wall_scene
    m = OccupancyMap()
    m.update(make_frame(K, T, depth))
    centres = wall_voxel_centres(K, T, margin_px=8)
    assert len(centres) > 50
    assert np.all(m.snapshot().state_at(centres) == 1)


def test_space_in_front_is_free_and_behind_is_unknown(wall_scene) -> None:
    K, T, depth = wall_scene
    m = OccupancyMap()
    m.update(make_frame(K, T, depth))
    snap = m.snapshot()
    rays = pixel_rays_world(K, T)
    v, u = np.meshgrid(np.arange(60, 180, 7), np.arange(80, 240, 7), indexing="ij")
    d = depth[v, u]
    assert np.all(np.isfinite(d))  # the central pixels all see the wall
    r = rays[v, u].reshape(-1, 3)
    d = d.ravel()[:, None]
    for frac in (0.2, 0.5, 0.8):
        in_front = CAM_POS + frac * (d - 0.25) * r  # stays a voxel and more before the wall
        assert np.all(snap.state_at(in_front) == 0)
    behind = CAM_POS + (d + 0.5) * r
    behind = behind[snap.contains(behind)]
    assert len(behind) > 50
    assert np.all(snap.state_at(behind) == -1)


def test_invalid_pixels_are_cleared_only_when_configured(wall_scene) -> None:
    K, T, depth = wall_scene
    u, v = 5, 120  # left edge, beyond the wall's end: NaN
    assert np.isnan(depth[v, u])
    probe = CAM_POS + 3.0 * pixel_rays_world(K, T)[v, u]
    cleared = OccupancyMap()
    cleared.update(make_frame(K, T, depth))
    skipped = OccupancyMap(type("SkipInvalid", (MapConfig,), {"clear_invalid_m": 0.0})())  # a class constant
    skipped.update(make_frame(K, T, depth))
    assert cleared.snapshot().state_at(probe[None])[0] == 0
    assert skipped.snapshot().state_at(probe[None])[0] == -1


def test_stereo_holes_do_not_clear_through_the_wall(wall_scene) -> None:
    K, T, depth = wall_scene
    holes = np.random.default_rng(3).random(depth.shape) < 0.1  # 10 % random dropouts
    holey = np.where(holes, np.nan, depth).astype(np.float32)
    rays = pixel_rays_world(K, T)
    v, u = np.meshgrid(np.arange(60, 180, 5), np.arange(80, 240, 5), indexing="ij")
    behind = (CAM_POS + (depth[v, u] + 0.6)[..., None] * rays[v, u]).reshape(-1, 3)
    guarded = OccupancyMap()
    guarded.update(make_frame(K, T, holey))
    naive = OccupancyMap(type("Unguarded", (MapConfig,), {"invalid_neighborhood_px": 0})())  # a class constant
    naive.update(make_frame(K, T, holey))
    inside = guarded.snapshot().contains(behind)
    assert np.all(guarded.snapshot().state_at(behind[inside]) == -1)
    assert np.all(guarded.snapshot().state_at(wall_voxel_centres(K, T, margin_px=8)) == 1)
    assert np.any(naive.snapshot().state_at(behind[inside]) == 0)  # without the guard holes see through


def test_detection_box_keeps_its_voxels_from_becoming_occupied(wall_scene) -> None:
    K, T, depth = wall_scene
    box = np.array([120.0, 80.0, 200.0, 160.0])
    masked = OccupancyMap()
    masked.update(make_frame(K, T, depth), [Detection(box_xyxy=box, score=0.9)])
    plain = OccupancyMap()
    plain.update(make_frame(K, T, depth))
    centres = wall_voxel_centres(K, T, margin_px=8)
    uv = project(K, T, centres)
    inside = np.all((uv >= box[:2] + 12) & (uv <= box[2:] - 12), axis=1)  # a voxel spans about 9 px here
    assert inside.sum() >= 4
    assert np.all(plain.snapshot().state_at(centres[inside]) == 1)
    assert not np.any(masked.snapshot().state_at(centres[inside]) == 1)
    outside = np.any((uv < box[:2] - 16) | (uv > box[2:] + 16), axis=1)
    assert np.all(masked.snapshot().state_at(centres[outside]) == 1)  # the rest of the wall is still seen


def test_hits_near_a_predicted_neighbour_are_not_mapped(wall_scene) -> None:
    """A neighbour the detector missed (depth hits, no box) is not mapped where the drone believes it is."""
    K, T, depth = wall_scene
    centres = wall_voxel_centres(K, T, margin_px=8)
    nb = np.array([X_WALL, 0.3, 1.5])  # where the drone's tracks / radio plans put a neighbour
    near = np.linalg.norm(centres - nb, axis=1) < 0.4 - 0.5 * VOXEL_M * np.sqrt(3)  # whole voxel inside the ball
    far = np.linalg.norm(centres - nb, axis=1) > 0.4 + VOXEL_M * np.sqrt(3)
    assert near.sum() >= 4 and far.sum() > 50
    excluded = OccupancyMap(MapConfig(neighbour_exclusion_m=0.4))
    excluded.update(make_frame(K, T, depth), (), nb[None])
    assert not np.any(excluded.snapshot().state_at(centres[near]) == 1)
    assert np.all(excluded.snapshot().state_at(centres[far]) == 1)
    off = OccupancyMap()  # the default: off
    off.update(make_frame(K, T, depth), (), nb[None])
    assert np.all(off.snapshot().state_at(centres[near]) == 1)


def test_wall_that_moved_back_is_erased_after_three_frames() -> None:
    K = intrinsics()
    T = camera_pose(np.array([0.0, 0.0, 1.5]), 0.0)
    near = wall_depth(K, T, X_WALL, 2.0, (0.3, 2.7))
    far = wall_depth(K, T, 4.37, 3.0, (0.0, 3.0))
    probe = np.array([[X_WALL, 0.0, 1.5]])
    m = OccupancyMap()
    m.update(make_frame(K, T, near))
    assert m.snapshot().state_at(probe)[0] == 1
    # log-odds 0.847 - 0.405 k: still occupied after 2 misses, free after 3
    expected = [1, 1, 0]
    for k, want in enumerate(expected):
        m.update(make_frame(K, T, far, time_s=0.04 * (k + 1)))
        assert m.snapshot().state_at(probe)[0] == want
    assert m.snapshot().state_at(np.array([[4.37, 0.0, 1.5]]))[0] == 1
    assert m.snapshot().time_s == pytest.approx(0.12)


def test_cylinder_hits_lie_on_its_surface() -> None:
    K = intrinsics()
    T = camera_pose(np.array([0.3, 0.4, 1.2]), -0.4)
    center = np.array([2.6, -0.7])
    radius = 0.6
    m = OccupancyMap()
    m.update(make_frame(K, T, cylinder_depth(K, T, center, radius)))
    snap = m.snapshot()
    occ = np.argwhere(snap.state == 1)
    assert len(occ) > 100
    c = snap.index_to_world(occ)
    radial = np.linalg.norm(c[:, :2] - center, axis=1) - radius
    assert np.abs(radial).max() <= np.sqrt(2) / 2 * VOXEL_M + 1e-9  # a hit voxel holds a surface point


def test_window_rolls_with_the_drone_and_keeps_what_it_saw(wall_scene) -> None:
    K, T, depth = wall_scene
    m = OccupancyMap()
    m.update(make_frame(K, T, depth))
    centres = wall_voxel_centres(K, T, margin_px=8)
    origin0 = m.origin_world.copy()
    pos2 = CAM_POS + np.array([-1.0, 1.2, 0.3])
    T2 = camera_pose(pos2, np.pi)  # moved and looking away from the wall
    m.update(make_frame(K, T2, np.full((H_PX, W_PX), np.nan, np.float32)))
    snap = m.snapshot()
    shift = (np.floor(pos2 / VOXEL_M) - np.floor(CAM_POS / VOXEL_M)) * VOXEL_M
    np.testing.assert_allclose(snap.origin_world - origin0, shift, atol=1e-9)
    assert np.all(np.abs(shift) > 0.1)
    assert np.all(snap.state_at(centres[snap.contains(centres)]) == 1)
    new_strip = snap.index_to_world(np.array([[snap.shape[0] - 1, snap.shape[1] - 1, 5]]))  # scrolled in, never seen
    assert snap.state_at(new_strip)[0] == -1


def test_each_voxel_keeps_the_time_a_ray_last_touched_it(wall_scene) -> None:
    K, T, depth = wall_scene
    fwd = np.array([np.cos(CAM_YAW), np.sin(CAM_YAW), 0.0])
    front, behind = CAM_POS + 1.5 * fwd, CAM_POS - 1.5 * fwd
    pos2 = CAM_POS + np.array([-0.6, 0.45, 0.0])  # moved (the window rolls) and looking away from the wall
    T2 = camera_pose(pos2, CAM_YAW + np.pi)
    nothing = np.full((H_PX, W_PX), np.nan, np.float32)  # no valid depth: rays clear up to clear_invalid_m

    m = OccupancyMap()
    m.update(make_frame(K, T, depth, time_s=1.0))
    snap1 = m.snapshot()
    seen = lambda snap, p: float(snap.seen_s[tuple(snap.world_to_index(p[None])[0])])  # noqa: E731
    assert seen(snap1, front) == 1.0 and seen(snap1, behind) == -np.inf
    m.update(make_frame(K, T2, nothing, time_s=3.5))
    snap = m.snapshot()
    assert seen(snap, front) == 1.0 and seen(snap, behind) == 3.5  # kept across the roll; restamped when seen
    assert snap.is_verified_free(front[None])[0]  # no age limit: free stays free
    assert snap.is_verified_free(front[None], max_age_s=2.6)[0]
    assert not snap.is_verified_free(front[None], max_age_s=2.4)[0]  # seen 2.5 s before the map's latest frame
    assert snap.is_verified_free(behind[None], max_age_s=0.1)[0]
    assert snap.seen_s.dtype == np.float32 and not snap.seen_s.flags.writeable


def test_snapshot_is_cached_and_read_only(wall_scene) -> None:
    K, T, depth = wall_scene
    m = OccupancyMap()
    m.update(make_frame(K, T, depth))
    s1 = m.snapshot()
    assert m.snapshot() is s1
    with pytest.raises(ValueError):
        s1.state[0, 0, 0] = 1
    m.update(make_frame(K, T, depth))
    assert m.snapshot() is not s1


@pytest.mark.parametrize(
    ("field", "value"),
    [("voxel_m", 0.05), ("window_size_m", (10.0, 10.0, 0.1)), ("pixel_stride", 0), ("log_odds_miss", 0.2),
     ("min_range_m", -0.1), ("max_range_m", 0.1), ("esdf_max_m", 0.0), ("clear_invalid_m", -1.0),
     ("invalid_neighborhood_px", -1), ("neighbour_exclusion_m", -0.1)],
)
def test_map_config_rejects_bad_values(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"^{field}="):
        if field in {f.name for f in dataclasses.fields(MapConfig)}:
            MapConfig(**{field: value})
        else:  # a class constant: a subclass overrides it
            type("Overridden", (MapConfig,), {field: value})()
