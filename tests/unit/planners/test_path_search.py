"""Front-end A* on an occupancy snapshot: detours, clearance, enclosure, unknown penalty, optimality."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import distance_transform_edt
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from perception.types import OccupancySnapshot
from planners.path_search import PathSearchConfig, search_path

VOXEL_M = 0.15
ORIGIN = np.array([-3.0, -3.0, 0.0])


def make_snapshot(occupied: np.ndarray, unknown: np.ndarray | None = None) -> OccupancySnapshot:
    """Snapshot whose ESDF is the exact signed EDT of ``occupied`` (nx, ny, nz), half-voxel surface convention."""
    state = np.zeros(occupied.shape, np.int8)
    if unknown is not None:
        state[unknown] = -1
    state[occupied] = 1
    out = distance_transform_edt(~occupied) * VOXEL_M - 0.5 * VOXEL_M
    inside = -(distance_transform_edt(occupied) * VOXEL_M - 0.5 * VOXEL_M)
    dist = np.where(occupied, inside, out).astype(np.float32)
    return OccupancySnapshot(0.0, ORIGIN.copy(), VOXEL_M, state, dist, dist)


def polyline_samples(points: np.ndarray, step_m: float = 0.01) -> np.ndarray:
    """Dense samples (n, 3) along a polyline (m, 3)."""
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:]):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step_m)))
        out.append(a + (b - a) * (np.arange(1, n + 1) / n)[:, None])
    return np.vstack(out)


def wall_grid() -> np.ndarray:
    """40 x 40 x 12 grid with a full-height wall at x index 20, open for y index >= 32."""
    occ = np.zeros((40, 40, 12), bool)
    occ[20, :32, :] = True
    return occ


def test_path_goes_around_a_wall_and_keeps_clearance() -> None:
    snap = make_snapshot(wall_grid())
    start, goal = np.array([-1.0, -1.0, 0.9]), np.array([1.0, -1.0, 0.9])
    clearance = 0.4
    res = search_path(snap, start, goal, clearance)
    assert res.found and res.path_world is not None and res.waypoints_world is not None
    np.testing.assert_allclose(res.waypoints_world[0], start)
    np.testing.assert_allclose(res.waypoints_world[-1], goal)
    # A* cells keep the clearance on the voxel grid
    d_cells, _ = snap.distance_and_gradient(res.path_world[1:-1])
    assert d_cells.min() >= clearance - 1e-6
    # the shortcut polyline stays clear too (up to interpolation between voxel centres)
    d_line, _ = snap.distance_and_gradient(polyline_samples(res.waypoints_world))
    assert d_line.min() >= clearance - 0.5 * VOXEL_M
    # it goes around the wall end (y index 32 -> y = 1.8 m), not through it
    wall_y_end = ORIGIN[1] + 32 * VOXEL_M
    assert res.path_world[:, 1].max() > wall_y_end + clearance - VOXEL_M
    assert len(res.waypoints_world) < len(res.path_world)


def test_enclosed_goal_returns_none() -> None:
    occ = np.zeros((30, 30, 12), bool)
    occ[18:25, 18:25, 2:9] = True
    occ[19:24, 19:24, 3:8] = False  # hollow box
    snap = make_snapshot(occ)
    goal = snap.index_to_world(np.array([[21, 21, 5]]))[0]
    res = search_path(snap, np.array([-2.0, -2.0, 0.9]), goal, 0.1, PathSearchConfig(goal_search_radius_m=0.2))
    assert not res.found
    assert res.status == "no_path"
    assert res.path_world is None and res.waypoints_world is None
    assert res.expanded_nodes > 0


def test_gap_narrower_than_twice_the_clearance_is_not_crossed() -> None:
    occ = np.zeros((40, 40, 12), bool)
    occ[20, :, :] = True
    occ[20, 18:22, :] = False  # 4-voxel (0.6 m) slot through the full-height wall
    snap = make_snapshot(occ)
    start, goal = np.array([-1.0, 0.0, 0.9]), np.array([1.0, 0.0, 0.9])
    assert search_path(snap, start, goal, 0.2).found
    assert search_path(snap, start, goal, 0.35).status == "no_path"


def test_unknown_penalty_prefers_known_free_space() -> None:
    occ = np.zeros((40, 40, 8), bool)
    unknown = np.zeros_like(occ)
    unknown[15:25, 0:30, :] = True  # an unknown slab across the direct route, known free around y index >= 30
    snap = make_snapshot(occ, unknown)
    start, goal = np.array([-1.5, -1.0, 0.6]), np.array([1.5, -1.0, 0.6])
    direct = search_path(snap, start, goal, 0.2, PathSearchConfig(unknown_penalty=0.0))
    careful = search_path(snap, start, goal, 0.2, PathSearchConfig(unknown_penalty=10.0))
    forbidden = search_path(snap, start, goal, 0.2, PathSearchConfig(allow_unknown=False))
    assert direct.found and careful.found and forbidden.found
    assert np.all(snap.state_at(direct.path_world) != 1)
    assert np.any(snap.state_at(direct.path_world) == -1)
    assert not np.any(snap.state_at(careful.path_world) == -1)
    assert not np.any(snap.state_at(forbidden.path_world) == -1)
    assert direct.cost_m < careful.cost_m


def test_goal_outside_window_is_clipped_towards_the_goal() -> None:
    snap = make_snapshot(np.zeros((40, 40, 12), bool))
    start = np.array([0.0, 0.0, 0.9])
    goal = np.array([20.0, 0.0, 0.9])
    res = search_path(snap, start, goal, 0.2)
    assert res.found and res.goal_clipped
    assert snap.contains(res.goal_used_world[None])[0]
    np.testing.assert_allclose(res.goal_used_world[1:], [0.0, 0.9], atol=1e-9)
    assert res.goal_used_world[0] == pytest.approx(snap.upper_world[0] - 0.5 * VOXEL_M)


def edge_block_grid() -> np.ndarray:
    """40 x 40 x 12 grid with a full-height block on the window's +x edge, astride y = 0 (a trunk cut by the edge)."""
    occ = np.zeros((40, 40, 12), bool)
    occ[34:, 14:27, :] = True
    return occ


def test_clipped_goal_blocked_at_the_edge_falls_back_to_the_window_voxel_nearest_the_goal() -> None:
    snap = make_snapshot(edge_block_grid())
    start, goal, clearance = np.array([-2.0, 0.0, 0.9]), np.array([20.0, 0.0, 0.9]), 0.4
    res = search_path(snap, start, goal, clearance, PathSearchConfig(goal_search_radius_m=1.0))
    assert res.found and res.goal_clipped and res.goal_fallback
    # the goal used is traversable and, of every traversable voxel of the window, the nearest to the true goal
    ok = (snap.state != OccupancySnapshot.OCCUPIED) & (snap.distance_m >= clearance)
    centres = snap.index_to_world(np.argwhere(ok))
    best = np.min(np.linalg.norm(centres - goal, axis=1))
    assert np.linalg.norm(res.goal_used_world - goal) == pytest.approx(best, abs=1e-9)
    assert snap.distance_and_gradient(res.goal_used_world[None])[0][0] >= clearance - 1e-6
    # it is beside the block on the window's far face, where the straight line left the window
    assert res.goal_used_world[0] == pytest.approx(snap.upper_world[0] - 0.5 * VOXEL_M)
    assert abs(res.goal_used_world[1]) > 1.0
    np.testing.assert_allclose(res.waypoints_world[-1], res.goal_used_world)


def pocket_grid() -> np.ndarray:
    """40 x 40 x 12 grid with a full-height U of walls open onto the window's +x edge, astride y = 0: the shadow
    behind a trunk, cut off inside the window (x index 31-39, y index 11-28)."""
    occ = np.zeros((40, 40, 12), bool)
    occ[30, 10:30, :] = True
    occ[30:, 10, :] = True
    occ[30:, 29, :] = True
    return occ


def test_clipped_goal_cut_off_in_a_pocket_falls_back_to_the_reachable_voxel_nearest_the_goal() -> None:
    from scipy.ndimage import label

    snap = make_snapshot(pocket_grid())
    start, goal, clearance = np.array([-2.0, 0.0, 0.9]), np.array([20.0, 0.0, 0.9]), 0.4
    # the clipped goal is traversable (the pocket is 2.7 m wide) but nothing leads into the pocket
    off = search_path(snap, start, goal, clearance, goal_fallback=False)
    assert off.status == "no_path" and off.goal_clipped and not off.goal_fallback
    assert off.goal_used_world[0] > 1.6  # inside the pocket
    res = search_path(snap, start, goal, clearance)
    assert res.found and res.goal_clipped and res.goal_fallback
    # the goal used is, of every voxel reachable from the start (26-connected traversable component), the nearest
    ok = (snap.state != OccupancySnapshot.OCCUPIED) & (snap.distance_m >= clearance)
    comp, _ = label(ok, structure=np.ones((3, 3, 3), bool))
    reach = comp == comp[tuple(snap.world_to_index(start[None])[0])]
    assert not reach[tuple(snap.world_to_index(off.goal_used_world[None])[0])]
    centres = snap.index_to_world(np.argwhere(reach))
    best = np.min(np.linalg.norm(centres - goal, axis=1))
    assert np.linalg.norm(res.goal_used_world - goal) == pytest.approx(best, abs=1e-9)
    # beside the U on the window's far face, and the path reaches it
    assert res.goal_used_world[0] == pytest.approx(snap.upper_world[0] - 0.5 * VOXEL_M)
    assert abs(res.goal_used_world[1]) > 1.5
    np.testing.assert_allclose(res.waypoints_world[-1], res.goal_used_world)


def test_a_cut_off_goal_with_no_progress_left_is_refused() -> None:
    # the start already stands where the reachable set comes nearest the goal: nothing to fall back to
    occ = np.zeros((40, 40, 12), bool)
    occ[30, :, :] = True  # a full wall across the window: the +x side is cut off from the start at x index 29
    snap = make_snapshot(occ)
    start = snap.index_to_world(np.array([[26, 20, 6]]))[0]
    res = search_path(snap, start, np.array([20.0, start[1], start[2]]), 0.4)
    assert res.status == "no_path" and res.goal_clipped and not res.goal_fallback


def test_fallback_is_only_for_a_clipped_goal() -> None:
    snap = make_snapshot(edge_block_grid())
    start = np.array([-2.0, 0.0, 0.9])
    inside = search_path(snap, start, np.array([2.6, 0.0, 0.9]), 0.4, PathSearchConfig(goal_search_radius_m=1.0))
    assert inside.status == "goal_blocked" and not inside.goal_clipped and not inside.goal_fallback
    # the caller may refuse it: a clipped goal blocked at the edge is then refused as before
    off = search_path(snap, start, np.array([20.0, 0.0, 0.9]), 0.4, PathSearchConfig(goal_search_radius_m=1.0), goal_fallback=False)
    assert off.status == "goal_blocked" and off.goal_clipped and not off.goal_fallback
    # a clipped goal free within the radius is moved as before, without the fallback
    free = search_path(snap, np.array([-2.0, -2.0, 0.9]), np.array([20.0, -2.0, 0.9]), 0.4)
    assert free.found and free.goal_clipped and not free.goal_fallback


def test_long_segments_are_split() -> None:
    snap = make_snapshot(np.zeros((40, 40, 12), bool))
    res = search_path(snap, np.array([-2.5, -2.5, 0.3]), np.array([2.5, 2.5, 1.5]), 0.1, PathSearchConfig(max_segment_m=1.0))
    assert res.found
    seg = np.linalg.norm(np.diff(res.waypoints_world, axis=0), axis=1)
    assert seg.max() <= 1.0 + 1e-9
    assert len(res.waypoints_world) >= 8  # straight 7.2 m line split into 1 m pieces


def test_astar_cost_matches_dijkstra_on_random_obstacles() -> None:
    rng = np.random.default_rng(7)
    shape = (14, 12, 6)
    occ = rng.random(shape) < 0.2
    occ[0, 0, 0] = occ[-1, -1, -1] = False
    unknown = (rng.random(shape) < 0.3) & ~occ
    snap = make_snapshot(occ, unknown)
    penalty = 0.5
    # graph of every allowed 26-connected move with the same costs as the search
    ok = ~occ
    idx = np.arange(occ.size).reshape(shape)
    rows, cols, w = [], [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if dx == dy == dz == 0:
                    continue
                src = idx[max(0, -dx) : shape[0] - max(0, dx), max(0, -dy) : shape[1] - max(0, dy), max(0, -dz) : shape[2] - max(0, dz)]
                dst = src + (dx * shape[1] + dy) * shape[2] + dz
                valid = ok.ravel()[src] & ok.ravel()[dst]
                length = VOXEL_M * np.sqrt(dx * dx + dy * dy + dz * dz)
                cost = np.where(unknown.ravel()[dst], (1 + penalty) * length, length)
                rows.append(src[valid])
                cols.append(dst[valid])
                w.append(cost[valid])
    graph = coo_matrix((np.concatenate(w), (np.concatenate(rows), np.concatenate(cols))), shape=(occ.size, occ.size))
    ref = dijkstra(graph.tocsr(), indices=0)[occ.size - 1]
    start = snap.index_to_world(np.array([[0, 0, 0]]))[0]
    goal = snap.index_to_world(np.array([[13, 11, 5]]))[0]
    res = search_path(snap, start, goal, 0.0, PathSearchConfig(unknown_penalty=penalty))
    assert np.isfinite(ref)  # this seed leaves a route
    assert res.found
    assert res.cost_m == pytest.approx(ref, rel=1e-3)  # tie-breaking allows 0.1 %


def test_start_inside_clearance_band_escapes() -> None:
    occ = np.zeros((40, 40, 12), bool)
    occ[20, :, :6] = True  # low wall, fly over it
    snap = make_snapshot(occ)
    start = snap.index_to_world(np.array([[18, 20, 3]]))[0]  # 0.3 m from the wall, clearance 0.4
    res = search_path(snap, start, np.array([2.0, 0.0, 0.6]), 0.4)
    assert res.found
    d, _ = snap.distance_and_gradient(res.path_world[1:-1])
    assert np.all(d[np.argmax(d >= 0.4) :] >= 0.4 - 1e-6)  # once out of the band it stays out


def test_altitude_band_is_respected() -> None:
    occ = np.zeros((40, 40, 12), bool)
    occ[20, :, :8] = True  # wall up to z = 1.2 m, open above
    snap = make_snapshot(occ)
    start, goal = np.array([-1.0, 0.0, 0.6]), np.array([1.0, 0.0, 0.6])
    over = search_path(snap, start, goal, 0.2)
    assert over.found and over.path_world[:, 2].max() > 1.2
    assert search_path(snap, start, goal, 0.2, PathSearchConfig(max_altitude_m=1.3)).status == "no_path"
    low = search_path(snap, start, np.array([1.0, 0.0, 0.05]), 0.0, PathSearchConfig(min_altitude_m=0.5))
    assert low.found and low.goal_used_world[2] >= 0.5  # a goal below the band moves up into it
    assert low.path_world[1:-1, 2].min() >= 0.5


def test_invalid_arguments_raise() -> None:
    snap = make_snapshot(np.zeros((10, 10, 10), bool))
    with pytest.raises(ValueError, match="start_world"):
        search_path(snap, np.array([50.0, 0.0, 0.0]), np.zeros(3), 0.1)
    with pytest.raises(ValueError, match="clearance_m"):
        search_path(snap, np.array([-2.5, -2.5, 0.5]), np.zeros(3), -1.0)
    with pytest.raises(ValueError, match="unknown_penalty"):
        PathSearchConfig(unknown_penalty=-1.0)
