"""ESDF: exact transform vs scipy, vs analytic distances, gradient vs finite differences, verified-free distance."""

from __future__ import annotations

import numpy as np
import pytest

from perception.esdf import compute_esdf, squared_edt, squared_edt_scipy
from perception.map_config import MapConfig
from perception.occupancy_map import OccupancyMap
from perception.types import DistanceField, OccupancySnapshot
from sim.types import RgbdFrame

VOXEL_M = 0.15
ORIGIN = np.array([-2.0, -1.5, -1.0])


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


def centres(shape: tuple[int, int, int]) -> np.ndarray:
    """Voxel centres (nx, ny, nz, 3) of a grid at ORIGIN."""
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), axis=-1)
    return ORIGIN + VOXEL_M * (idx + 0.5)


def sphere_snapshot(center: np.ndarray, radius_m: float, shape=(30, 26, 22), max_m: float = 10.0) -> OccupancySnapshot:
    """Snapshot of a voxelised solid sphere (voxels whose centre lies inside), everything else free."""
    c = centres(shape)
    occupied = np.linalg.norm(c - center, axis=-1) <= radius_m
    state = np.where(occupied, 1, 0).astype(np.int8)
    distance_m, free_m = compute_esdf(occupied, ~occupied, VOXEL_M, max_m)
    return OccupancySnapshot(0.0, ORIGIN.copy(), VOXEL_M, state, distance_m, free_m)


@pytest.mark.parametrize("shape", [(17, 13, 9), (40, 3, 2), (2, 2, 2)])
def test_numba_transform_equals_scipy(rng, shape) -> None:
    feature = rng.random(shape) < 0.05
    feature.flat[0] = True
    np.testing.assert_allclose(squared_edt(feature), squared_edt_scipy(feature), rtol=0, atol=1e-9)


def test_transform_without_features_is_far_everywhere() -> None:
    assert np.all(squared_edt(np.zeros((5, 4, 3), bool)) >= 1e19)
    distance_m, free_m = compute_esdf(np.zeros((5, 4, 3), bool), np.ones((5, 4, 3), bool), VOXEL_M, 2.0)
    assert np.all(distance_m == np.float32(2.0))
    assert free_m.max() == pytest.approx(1.5 * VOXEL_M)  # the window's outside is not verified free


def test_esdf_matches_exact_distance_to_a_sphere_within_a_voxel() -> None:
    center, radius = np.array([0.3, 0.4, 0.6]), 0.7
    snap = sphere_snapshot(center, radius)
    c = centres(snap.shape)
    exact = np.linalg.norm(c - center, axis=-1) - radius
    err = snap.distance_m - exact
    assert np.abs(err).max() <= VOXEL_M
    assert np.all(snap.distance_m[snap.state == 1] < 0)
    assert np.all(snap.distance_m[snap.state == 0] > 0)
    # between voxel centres, the trilinear interpolant stays within a voxel too
    pts = np.random.default_rng(5).uniform(ORIGIN + 0.1, ORIGIN + VOXEL_M * np.asarray(snap.shape) - 0.1, (500, 3))
    d, _ = snap.distance_and_gradient(pts)
    assert np.abs(d - (np.linalg.norm(pts - center, axis=1) - radius)).max() <= VOXEL_M


def test_esdf_is_truncated() -> None:
    snap = sphere_snapshot(np.array([0.3, 0.4, 0.6]), 0.4, max_m=0.9)
    assert snap.distance_m.max() == pytest.approx(0.9)
    assert snap.free_distance_m.max() <= 0.9 + 1e-6


def test_gradient_matches_finite_differences(rng) -> None:
    snap = sphere_snapshot(np.array([0.3, 0.4, 0.6]), 0.7)
    assert isinstance(snap, DistanceField)
    pts = rng.uniform(ORIGIN + 0.2, ORIGIN + VOXEL_M * np.asarray(snap.shape) - 0.2, (300, 3))
    _, grad = snap.distance_and_gradient(pts)
    eps = 1e-6
    fd = np.stack(
        [
            (snap.distance_and_gradient(pts + eps * e)[0] - snap.distance_and_gradient(pts - eps * e)[0]) / (2 * eps)
            for e in np.eye(3)
        ],
        axis=1,
    )
    np.testing.assert_allclose(grad, fd, atol=1e-5)


def test_gradient_points_away_from_the_obstacle(rng) -> None:
    center = np.array([0.3, 0.4, 0.6])
    snap = sphere_snapshot(center, 0.7)
    direction = rng.normal(size=(200, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    pts = center + (0.7 + rng.uniform(0.4, 0.9, (200, 1))) * direction
    pts = pts[snap.contains(pts)]
    _, grad = snap.distance_and_gradient(pts)
    normal = (pts - center) / np.linalg.norm(pts - center, axis=1, keepdims=True)
    cos = np.sum(grad * normal, axis=1) / np.linalg.norm(grad, axis=1)
    assert np.median(cos) > 0.99
    assert cos.min() > 0.9


def test_queries_outside_the_window_clamp_to_the_boundary() -> None:
    snap = sphere_snapshot(np.array([0.3, 0.4, 0.6]), 0.7)
    inside = snap.index_to_world(np.array([[snap.shape[0] - 1, 5, 5]]))[0]
    outside = inside + np.array([3.0, 0.0, 0.0])
    d_in, _ = snap.distance_and_gradient(inside[None])
    d_out, g_out = snap.distance_and_gradient(outside[None])
    assert d_out[0] == pytest.approx(d_in[0])
    assert g_out[0, 0] == 0.0
    assert snap.state_at(outside[None])[0] == OccupancySnapshot.UNKNOWN


def test_verified_free_distance_counts_unknown_and_the_window_edge() -> None:
    shape = (30, 30, 20)
    free = np.zeros(shape, bool)
    free[5:25, 8:22, 4:16] = True  # a verified-free box, unknown around it, nothing occupied
    distance_m, free_m = compute_esdf(np.zeros(shape, bool), free, VOXEL_M, 10.0)
    assert np.all(distance_m == np.float32(10.0))  # unknown is free for the ESDF
    c = np.argwhere(free)
    to_face = np.minimum(c - [5, 8, 4], [24, 21, 15] - c).min(axis=1) + 0.5  # voxels to the nearest box face
    np.testing.assert_allclose(free_m[free], to_face * VOXEL_M, atol=1e-5)
    assert np.all(free_m[~free] == 0.0)


def test_map_esdf_matches_distance_to_a_seen_cylinder() -> None:
    """End to end: one analytic depth frame of a pillar; the ESDF in front of it within the voxelisation bound."""
    w_px, h_px = 320, 240
    fx, fy = (w_px / 2) / np.tan(np.radians(42.5)), (h_px / 2) / np.tan(np.radians(29.0))
    K = np.array([[fx, 0.0, (w_px - 1) / 2], [0.0, fy, (h_px - 1) / 2], [0.0, 0.0, 1.0]])
    cam = np.array([0.0, 0.0, 1.5])
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # looks along world +x
    T[:3, 3] = cam
    center, radius = np.array([3.0, 0.2]), 0.5
    u, v = np.meshgrid(np.arange(w_px, dtype=float), np.arange(h_px, dtype=float))
    rays = np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(K).T @ T[:3, :3].T
    oxy = cam[:2] - center
    a = np.sum(rays[..., :2] ** 2, -1)
    b = 2 * np.sum(rays[..., :2] * oxy, -1)
    disc = b**2 - 4 * a * (oxy @ oxy - radius**2)
    with np.errstate(invalid="ignore"):
        s = (-b - np.sqrt(disc)) / (2 * a)
    depth = np.where((disc >= 0) & (s > 0.2) & (s < 10), s, np.nan).astype(np.float32)
    m = OccupancyMap(type("FullResolution", (MapConfig,), {"pixel_stride": 1})())  # a class constant
    m.update(RgbdFrame(0, 0.0, np.zeros((h_px, w_px, 3), np.uint8), depth, K, T))
    snap = m.snapshot()
    # points on the camera's side, within 25 deg of the line of sight and 0.3-1.5 m from the surface
    ang = np.radians(np.linspace(-25, 25, 11))
    rad = radius + np.linspace(0.3, 1.5, 9)
    aa, rr = np.meshgrid(ang, rad)
    to_cam = (cam[:2] - center) / np.linalg.norm(cam[:2] - center)
    rot = np.stack([np.cos(aa) * to_cam[0] - np.sin(aa) * to_cam[1], np.sin(aa) * to_cam[0] + np.cos(aa) * to_cam[1]], -1)
    pts_xy = center + rr[..., None] * rot
    pts = np.column_stack([pts_xy.reshape(-1, 2), np.full(pts_xy.size // 2, 1.5)])
    assert np.all(snap.is_verified_free(pts))
    d, _ = snap.distance_and_gradient(pts)
    exact = np.linalg.norm(pts[:, :2] - center, axis=1) - radius
    # a hit voxel's centre lies within sqrt(2)/2 voxel (in xy) of the surface point it holds, and the
    # field reads half a voxel less than the centre distance: d - exact in [-(1 + sqrt 2)/2, (sqrt 2 - 1)/2] voxels
    err = d - exact
    assert err.min() >= -(1 + np.sqrt(2)) / 2 * VOXEL_M - 0.01
    assert err.max() <= (np.sqrt(2) - 1) / 2 * VOXEL_M + 0.01
    assert np.abs(err).mean() <= VOXEL_M


def test_world_index_round_trip(rng) -> None:
    snap = sphere_snapshot(np.array([0.3, 0.4, 0.6]), 0.5)
    idx = np.column_stack([rng.integers(0, n, 50) for n in snap.shape])
    np.testing.assert_array_equal(snap.world_to_index(snap.index_to_world(idx)), idx)
    pts = rng.uniform(snap.origin_world, snap.upper_world, (200, 3))
    assert np.all(np.abs(snap.index_to_world(snap.world_to_index(pts)) - pts) <= 0.5 * VOXEL_M + 1e-12)
    assert np.all(snap.contains(pts))
    assert not snap.contains((snap.upper_world + 0.01)[None])[0]
    np.testing.assert_array_equal(snap.is_verified_free(pts), snap.state_at(pts) == 0)


@pytest.mark.parametrize("fill", [0.05, 0.6, 0.97, 1.0])
def test_signed_distance_equals_the_two_transform_field_to_the_bit(rng, fill) -> None:
    """The inside distance comes from a local search (``_inside_squared``), not a second transform: same field."""
    from perception.esdf import _signed_field, signed_distance

    for shape, max_m in (((17, 13, 9), 3.0), ((30, 26, 22), 0.5), ((40, 3, 2), 1.0)):
        occupied = rng.random(shape) < fill
        c = np.array(shape) // 2
        occupied |= np.sum((np.indices(shape).transpose(1, 2, 3, 0) - c) ** 2, axis=-1) <= 16  # a thick solid ball
        two = _signed_field(occupied, squared_edt(occupied), squared_edt(~occupied), VOXEL_M, max_m)
        np.testing.assert_array_equal(signed_distance(occupied, VOXEL_M, max_m), two)


@pytest.mark.parametrize("max_m", [0.3, 0.5, 3.0, np.inf])
def test_signed_distance_inside_a_thick_wall_past_the_search_radius(max_m) -> None:
    """A wall 24 voxels thick: its core lies beyond the search radius of small truncations (the clip takes
    over), and a window almost all wall exhausts the search's budget (the transform takes over)."""
    from perception.esdf import _inside_squared, _signed_field, signed_distance

    for shape, wall in (((40, 30, 12), slice(8, 32)), ((30, 30, 30), slice(0, 30))):
        occupied = np.zeros(shape, bool)
        occupied[wall] = True
        occupied[wall.start if wall.start else 3, 15, 6] = False  # a pocket
        two = _signed_field(occupied, squared_edt(occupied), squared_edt(~occupied), VOXEL_M, max_m)
        np.testing.assert_array_equal(signed_distance(occupied, VOXEL_M, max_m), two)
    assert not _inside_squared(np.ones((30, 30, 30), bool), 30, 8 * 30**3)[1]  # solid: handed to the transform
