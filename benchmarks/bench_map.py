"""Benchmark of the onboard map: depth-frame insertion, ESDF, front-end A*.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_map.py``.

Scene: a forest of vertical cylinders (seeded) on a ground plane, one analytic
320 x 240 depth frame from a camera at 1.5 m. Prints the median of repeats and
ratios against baselines measured in the same run:

* insertion: the numba voxel traversal (default stride 2, and full resolution)
  against a vectorised numpy baseline that samples every ray at half-voxel
  steps and deduplicates with ``np.unique`` (same hit-wins rule);
* back-projection: the map's numpy depth -> world points against open3d's
  ``PointCloud.create_from_depth_image`` (the map keeps numpy);
* ESDF: the numba Felzenszwalb transform against ``scipy.ndimage.distance_transform_edt``;
* A*: on voxelised forests (two densities) 10 m x 10 m x 3 m at 0.15 m, random start/goal pairs,
  against scipy's Dijkstra (``scipy.sparse.csgraph``) on the same 26-connected graph.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from perception.esdf import compute_esdf
from perception.map_config import MapConfig
from perception.occupancy_map import OccupancyMap
from perception.types import OccupancySnapshot
from planners.path_search import search_path
from sim.types import RgbdFrame

import timing  # benchmarks/timing.py, beside this script

W_PX, H_PX = 320, 240
REPEATS = 15


def median_ms(fn, repeats: int = REPEATS) -> float:
    """:func:`timing.median_ms` with this benchmark's default repeats."""
    return timing.median_ms(fn, repeats)


def forest(rng: np.random.Generator, half_m: float = 10.0, density_per_m2: float = 0.08) -> np.ndarray:
    """Trees (n, 3): centre x, y [m] and radius [m], none within 1 m of the origin."""
    n = int(density_per_m2 * (2 * half_m) ** 2)
    xy = rng.uniform(-half_m, half_m, (n, 2))
    xy = xy[np.linalg.norm(xy, axis=1) > 1.0]
    return np.column_stack([xy, rng.uniform(0.15, 0.4, len(xy))])


def forest_frame(trees: np.ndarray) -> RgbdFrame:
    """Analytic depth frame of the forest and the ground from a camera at (0, 0, 1.5) looking along +x."""
    fx, fy = (W_PX / 2) / np.tan(np.radians(42.5)), (H_PX / 2) / np.tan(np.radians(29.0))
    K = np.array([[fx, 0.0, (W_PX - 1) / 2], [0.0, fy, (H_PX - 1) / 2], [0.0, 0.0, 1.0]])
    T = np.eye(4)
    T[:3, :3] = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    T[:3, 3] = [0.0, 0.0, 1.5]
    u, v = np.meshgrid(np.arange(W_PX, dtype=float), np.arange(H_PX, dtype=float))
    r = (np.stack([u, v, np.ones_like(u)], -1) @ np.linalg.inv(K).T @ T[:3, :3].T).reshape(-1, 3)
    o = T[:3, 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(r[:, 2] < 0, -o[2] / r[:, 2], np.inf)  # ground z = 0
        for cx, cy, rad in trees:
            oxy = o[:2] - (cx, cy)
            a = np.sum(r[:, :2] ** 2, 1)
            b = 2 * r[:, :2] @ oxy
            disc = b**2 - 4 * a * (oxy @ oxy - rad**2)
            t = (-b - np.sqrt(np.maximum(disc, 0))) / (2 * a)
            s = np.where((disc >= 0) & (t > 0), np.minimum(s, t), s)
    depth = np.where((s >= 0.2) & (s <= 10.0), s, np.nan).reshape(H_PX, W_PX).astype(np.float32)
    return RgbdFrame(0, 0.0, np.zeros((H_PX, W_PX, 3), np.uint8), depth, K, T)


def insert_numpy(m: OccupancyMap, frame: RgbdFrame) -> None:
    """Baseline insertion: sample the same rays (each from its start fraction) every half voxel, deduplicate with np.unique, hit wins."""
    cfg = m.config
    T = frame.transform_camera_to_world
    m.recenter(T[:3, 3])
    ends_cam, is_hit, start = m._rays_camera(frame, ())
    ends = ends_cam @ T[:3, :3].T + T[:3, 3]
    o0 = (T[:3, 3] - m.origin_world) / cfg.voxel_m
    e = (ends - m.origin_world) / cfg.voxel_m
    o = o0 + (e - o0) * start[:, None]  # an untraversed hit ray starts at its tail
    n_s = np.maximum(1, np.ceil(2 * np.linalg.norm(e - o, axis=1)).astype(np.int64))
    ray = np.repeat(np.arange(len(e)), n_s)
    k = np.arange(n_s.sum()) - np.repeat(np.cumsum(n_s) - n_s, n_s)
    pts = o[ray] + (e[ray] - o[ray]) * (k / n_s[ray])[:, None]
    shape = np.asarray(m._log_odds.shape)
    idx = np.floor(pts).astype(np.int64)
    inside = np.all((idx >= 0) & (idx < shape), axis=1)
    free_lin = np.unique(np.ravel_multi_index(idx[inside].T, shape))
    hit_idx = np.floor(e[is_hit]).astype(np.int64)
    hit_idx = hit_idx[np.all((hit_idx >= 0) & (hit_idx < shape), axis=1)]
    hit_lin = np.unique(np.ravel_multi_index(hit_idx.T, shape))
    free_lin = np.setdiff1d(free_lin, hit_lin, assume_unique=True)
    lo = m._log_odds.reshape(-1)
    lo[free_lin] = np.clip(lo[free_lin] + cfg.log_odds_miss, cfg.log_odds_min, cfg.log_odds_max)
    lo[hit_lin] = np.clip(lo[hit_lin] + cfg.log_odds_hit, cfg.log_odds_min, cfg.log_odds_max)
    m._observed.reshape(-1)[np.concatenate([free_lin, hit_lin])] = True
    m._snapshot = None


def forest_snapshot(trees: np.ndarray, voxel_m: float = 0.15) -> OccupancySnapshot:
    """Fully known voxelised forest, 10 m x 10 m x 3 m, ground layer occupied."""
    shape = (67, 67, 20)
    origin = np.array([-5.025, -5.025, -0.15])
    idx = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), -1)
    c = origin + voxel_m * (idx + 0.5)
    occ = c[..., 2] < 0.0
    for cx, cy, rad in trees:
        occ |= np.hypot(c[..., 0] - cx, c[..., 1] - cy) <= rad
    state = occ.astype(np.int8)
    distance_m, free_m = compute_esdf(occ, ~occ, voxel_m, 3.0)
    return OccupancySnapshot(0.0, origin, voxel_m, state, distance_m, free_m)


def dijkstra_graph(snap: OccupancySnapshot, clearance_m: float):
    """scipy CSR graph of the 26-connected moves between traversable voxels."""
    shape = snap.shape
    ok = ((snap.state != 1) & (snap.distance_m >= clearance_m)).ravel()
    idx = np.arange(ok.size).reshape(shape)
    rows, cols, w = [], [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            for dz in (-1, 0, 1):
                if dx == dy == dz == 0:
                    continue
                sl = tuple(slice(max(0, -d), n - max(0, d)) for d, n in zip((dx, dy, dz), shape))
                src = idx[sl].ravel()
                dst = src + (dx * shape[1] + dy) * shape[2] + dz
                keep = ok[src] & ok[dst]
                rows.append(src[keep])
                cols.append(dst[keep])
                w.append(np.full(keep.sum(), snap.voxel_m * np.sqrt(dx * dx + dy * dy + dz * dz)))
    n = ok.size
    return coo_matrix((np.concatenate(w), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n)).tocsr()


def main() -> None:
    rng = np.random.default_rng(0)
    trees = forest(rng)
    frame = forest_frame(trees)
    print(f"frame {W_PX}x{H_PX}, {np.isfinite(frame.depth_m).mean():.0%} valid pixels, {len(trees)} trees")

    print("\n-- insert one frame (median ms) --")
    res = {}
    full_resolution = type("FullResolution", (MapConfig,), {"pixel_stride": 1})  # pixel_stride is a class constant
    for name, cfg in [("numba stride 2 (default)", MapConfig()), ("numba stride 1", full_resolution())]:
        m = OccupancyMap(cfg)
        res[name] = median_ms(lambda: m.update(frame))
    m_np = OccupancyMap(MapConfig())
    res["numpy sampled rays, stride 2 (baseline)"] = median_ms(lambda: insert_numpy(m_np, frame))
    base = res["numpy sampled rays, stride 2 (baseline)"]
    for name, ms in res.items():
        print(f"{name:42s} {ms:8.2f} ms   x{base / ms:5.1f} vs numpy baseline")

    print("\n-- depth -> world points only, stride 2 (median ms) --")
    bench_backprojection(frame)

    print("\n-- ESDF over the window (median ms) --")
    m = OccupancyMap()
    m.update(frame)
    state = m.state()
    occ, free = state == 1, state == 0
    print(f"window {state.shape} voxels, {occ.sum()} occupied, {free.sum()} free")
    t_numba = median_ms(lambda: compute_esdf(occ, free, 0.15, 3.0))
    t_scipy = median_ms(lambda: compute_esdf(occ, free, 0.15, 3.0, use_scipy=True))
    print(f"{'numba Felzenszwalb':42s} {t_numba:8.2f} ms   x{t_scipy / t_numba:5.1f} vs scipy")
    print(f"{'scipy distance_transform_edt (baseline)':42s} {t_scipy:8.2f} ms")

    def insert_and_snapshot() -> None:
        m.update(frame)
        m.snapshot()

    print(f"{'insert + ESDF snapshot (default config)':42s} {median_ms(insert_and_snapshot):8.2f} ms")

    for density in (0.08, 0.3):
        bench_astar(forest(np.random.default_rng(1), half_m=5.0, density_per_m2=density), density, rng)

    print("\n-- the denied stack's per-frame kernels, compiled against their numpy references (median ms) --")
    bench_kernels(m, frame, occ)


def bench_kernels(m: OccupancyMap, frame: RgbdFrame, occ: np.ndarray) -> None:
    """Each compiled kernel against the numpy code it replaced (the tests hold them equal to the bit)."""
    from perception.backprojection import box_depth_m, box_depth_numpy
    from perception.esdf import _signed_field, signed_distance, squared_edt
    from perception.occupancy_map import _clearance, clearance_numpy
    from planners.neighbour_field import _capsule_block, capsule_block_numpy

    def row(name: str, fast, slow) -> None:  # noqa: ANN001
        t_fast, t_slow = median_ms(fast), median_ms(slow)
        print(f"{name:42s} {t_fast:8.3f} ms   numpy {t_slow:8.3f} ms   x{t_slow / t_fast:5.1f}")

    snap = m.snapshot()
    dist = np.ascontiguousarray(snap.distance_m)
    origin = np.asarray(snap.origin_world, float)
    pts = origin + np.random.default_rng(3).uniform(0.5, 9.5, (40, 3)) * [1, 1, 0.35]  # a plan's 40 samples
    centres = origin + (np.random.default_rng(4).integers(0, 60, (50, 3)) + 0.5) * 0.15  # 50 newly occupied voxels
    row("clearance (40 points, 50 new voxels)", lambda: _clearance(dist, origin, 0.15, pts, centres), lambda: clearance_numpy(dist, origin, 0.15, pts, centres))
    row("ESDF, inside by search vs transform", lambda: signed_distance(occ, 0.15, 3.0),
        lambda: _signed_field(occ, squared_edt(occ), squared_edt(~occ), 0.15, 3.0))
    a = origin + np.array([5.0, 5.0, 1.5])
    b = a + np.array([1.0, 0.3, 0.0])  # 1 m/s over the 1 s conflict horizon
    lo = np.clip(np.floor((np.minimum(a, b) - 2.0 - origin) / 0.15).astype(int), 0, dist.shape)
    hi = np.clip(np.ceil((np.maximum(a, b) + 2.0 - origin) / 0.15).astype(int) + 1, 0, dist.shape)
    buf = dist.copy()
    row("one neighbour capsule (front end)", lambda: _capsule_block(buf, origin, 0.15, lo, hi, a, b - a, float((b - a) @ (b - a)), 0.7, 1.3),
        lambda: capsule_block_numpy(buf, origin, 0.15, lo, hi, a, b, 0.7, 1.3))
    box = np.array([100.0, 130.0, 140.0, 160.0])  # a box on the forest, 37 % of it valid depth
    row("a detection's foreground depth", lambda: box_depth_m(frame.depth_m, box), lambda: box_depth_numpy(frame.depth_m, box))


def bench_backprojection(frame: RgbdFrame) -> None:
    """The map's numpy back-projection against open3d's ``PointCloud.create_from_depth_image``."""
    m = OccupancyMap()
    T = frame.transform_camera_to_world

    def numpy_points() -> np.ndarray:
        ends_cam, is_hit, _ = m._rays_camera(frame, ())
        return ends_cam[is_hit] @ T[:3, :3].T + T[:3, 3]

    t_np = median_ms(numpy_points)
    try:
        import open3d as o3d
    except ImportError:
        print(f"{'numpy (the map)':42s} {t_np:8.2f} ms   (open3d not installed, no comparison)")
        return
    K = frame.K
    intrinsic = o3d.camera.PinholeCameraIntrinsic(W_PX, H_PX, K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    extrinsic = np.linalg.inv(T)  # open3d takes world -> camera

    def open3d_points() -> np.ndarray:
        depth = np.nan_to_num(frame.depth_m, nan=0.0)  # open3d skips zero depth
        pcd = o3d.geometry.PointCloud.create_from_depth_image(
            o3d.geometry.Image(depth), intrinsic, extrinsic, depth_scale=1.0, depth_trunc=10.0, stride=2
        )
        return np.asarray(pcd.points)

    t_o3d = median_ms(open3d_points)
    n_np, n_o3d = len(numpy_points()), len(open3d_points())
    print(f"{'numpy (the map)':42s} {t_np:8.2f} ms   x{t_o3d / t_np:5.1f} vs open3d ({n_np} points)")
    print(f"{'open3d create_from_depth_image':42s} {t_o3d:8.2f} ms   ({n_o3d} points)")


def bench_astar(trees: np.ndarray, density: float, rng: np.random.Generator) -> None:
    """Median A* time over 20 random start/goal pairs more than 6 m apart, and scipy Dijkstra."""
    clearance = 0.3
    print(f"\n-- A* on a voxelised forest 10 x 10 x 3 m at 0.15 m, {density} trees/m^2, clearance {clearance} m --")
    snap = forest_snapshot(trees)
    ok = (snap.state != 1) & (snap.distance_m >= clearance)
    cand = snap.index_to_world(np.argwhere(ok[:, :, 8:12]) + [0, 0, 8])
    pairs = []
    while len(pairs) < 20:
        a, b = cand[rng.integers(len(cand), size=2)]
        if np.linalg.norm(a[:2] - b[:2]) > 6.0:
            pairs.append((a, b))
    times, expanded, found = [], [], 0
    for a, b in pairs:
        times.append(median_ms(lambda: search_path(snap, a, b, clearance), repeats=3))
        r = search_path(snap, a, b, clearance)
        expanded.append(r.expanded_nodes)
        found += r.found
    graph = dijkstra_graph(snap, clearance)
    t_dij = []
    for a, _ in pairs[:5]:
        source = int(np.ravel_multi_index(tuple(snap.world_to_index(a[None])[0]), snap.shape))
        t_dij.append(median_ms(lambda: dijkstra(graph, indices=source), repeats=3))
    t_astar = float(np.median(times))
    print(f"{'numba A* + shortcut':42s} {t_astar:8.2f} ms   ({found}/20 found, median {int(np.median(expanded))} "
          f"expansions, max {max(times):.2f} ms)")
    print(f"{'scipy Dijkstra, same graph (baseline)':42s} {np.median(t_dij):8.2f} ms   x{np.median(t_dij) / t_astar:5.1f}")

if __name__ == "__main__":
    main()
