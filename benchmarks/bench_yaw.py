"""Benchmark: one ``YawPlanner.plan`` call in exploring mode (MP-CDE Sec. IV-A, Alg. 1).

Scene: a 10 x 10 x 4 m map window at 0.15 m voxels (67 x 67 x 27) around a
drone at 1.5 m altitude flying at 1 m/s; up to 25 trees (cylinders of radius
0.15-0.35 m, none within 2.3 m of the drone) placed by a seeded generator; the
camera has seen a disc of 2.6 m around the drone and a 150 deg wedge ahead out
to 4.5 m (verified free where no tree is, occupied on the trees, unknown
behind them); the rest of the window is unknown. Three
neighbours, two of them not seen for more than t_hold (so the plan explores
with a visibility term). The coverage window holds ten past yaws, as after
1 s of planning.

Prints the median [ms] of one ``plan()`` call (default settings: 12 layers,
64 candidates, a 305-ray fan per layer) and of its two largest parts (the fan
cast, the Dijkstra search on this plan's edge costs), against two baselines
measured in the same run: the same 12 x 305 rays cast by a per-ray,
per-sample Python loop (same rays, same result: the vectorisation alone), and
the whole exploring plan done the straightforward way, every candidate's
sector cast by that loop at every layer (72 rays x 64 candidates x 12 layers,
55,296 rays: the vectorisation and the shared fan together), checked to give
the same yaws. Goal (task
brief): <= 5 ms median for one ``plan()`` with default settings.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_yaw.py [--repeats N]``.
"""

from __future__ import annotations

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import math  # noqa: E402

import numpy as np  # noqa: E402
from scipy.ndimage import distance_transform_edt  # noqa: E402
from timing import median_ms  # noqa: E402

from perception.types import NeighborPrediction, OccupancySnapshot  # noqa: E402
from planners.yaw import (  # noqa: E402
    FanGeometry,
    TrajectoryView,
    YawPlanner,
    YawPlannerConfig,
    cast_fans,
    edge_costs,
    edge_gains,
    past_coverage,
    ray_gains,
    shortest_path,
    visibility_rewards,
)
from planners.yaw.safety import safety_margin  # noqa: E402

VOXEL_M = 0.15
SIZE_M = np.array([10.0, 10.0, 4.0])
ALTITUDE_M = 1.5
SPEED_MPS = 1.0


def forest_snapshot(seed: int = 0, n_trees: int = 25) -> OccupancySnapshot:
    """The benchmark's map window, drone at its centre (0, 0, 1.5) facing +x (see the module docstring)."""
    rng = np.random.default_rng(seed)
    origin = np.array([-5.0, -5.0, 0.0])
    shape = tuple(int(math.ceil(s / VOXEL_M)) for s in SIZE_M)
    centres = origin + VOXEL_M * (np.indices(shape).reshape(3, -1).T + 0.5)
    trees = rng.uniform(-4.5, 4.5, (n_trees, 2))
    radii = rng.uniform(0.15, 0.35, n_trees)
    clear = np.linalg.norm(trees, axis=1) - radii > 2.3  # S(0) > tau_thr + 0.1 s needs > 2 m of free space at 1 m/s
    trees, radii = trees[clear], radii[clear]
    dist_tree = np.min(np.linalg.norm(centres[:, None, :2] - trees[None], axis=2) - radii[None], axis=1)
    occupied = (dist_tree <= 0.0).reshape(shape)
    rel = centres[:, :2]
    r = np.linalg.norm(rel, axis=1)
    wedge = (np.abs(np.arctan2(rel[:, 1], rel[:, 0])) <= math.radians(75)) & (r <= 4.5)
    seen = (wedge | (r <= 2.6)).reshape(shape)
    # what the camera saw: free up to the first tree along each ray from the drone, the tree's surface occupied
    state = np.full(shape, OccupancySnapshot.UNKNOWN, np.int8)
    state[seen] = OccupancySnapshot.FREE
    for (tx, ty), tr in zip(trees, radii):
        t_r, t_b = math.hypot(tx, ty), math.atan2(ty, tx)
        half = math.asin(min(1.0, (tr + VOXEL_M) / t_r))
        b = np.arctan2(rel[:, 1], rel[:, 0])
        behind = ((np.abs((b - t_b + np.pi) % (2 * np.pi) - np.pi) <= half) & (r > t_r)).reshape(shape)
        state[behind & seen] = OccupancySnapshot.UNKNOWN
    state[occupied & seen] = OccupancySnapshot.OCCUPIED
    dist = (distance_transform_edt(~occupied) * VOXEL_M).astype(np.float32)
    free = (distance_transform_edt(state == OccupancySnapshot.FREE) * VOXEL_M).astype(np.float32)
    return OccupancySnapshot(0.0, origin, VOXEL_M, state, dist, free)


def straight_line(t0_s: float = 0.0, duration_s: float = 3.0) -> TrajectoryView:
    """Flight along +x at 1 m/s and 1.5 m altitude from the window's centre."""
    start = np.array([0.0, 0.0, ALTITUDE_M])
    vel = np.array([SPEED_MPS, 0.0, 0.0])
    return TrajectoryView(
        position_at=lambda t: start + (np.asarray(t)[:, None] - t0_s) * vel,
        velocity_at=lambda t: np.broadcast_to(vel, (np.size(t), 3)).copy(),
        end_time_s=t0_s + duration_s,
    )


def neighbours(time_s: float) -> list[NeighborPrediction]:
    """Three perception tracks: one seen just now, two not for 0.8 s and 1.0 s (more than t_hold)."""
    cov = np.diag([0.02, 0.02, 0.02, 0.1, 0.1, 0.1])
    out = []
    for k, (pos, vel, age) in enumerate(
        [((3.0, 1.0, 1.5), (0.0, -0.5, 0.0), 0.0), ((-1.0, 3.0, 1.4), (0.3, 0.0, 0.0), 0.8),
         ((0.5, -4.0, 1.6), (0.0, 0.4, 0.0), 1.0)]
    ):
        out.append(NeighborPrediction.constant_velocity(k, "perception", time_s - age, pos, vel, cov))
    return out


def warm_planner(snapshot: OccupancySnapshot, trajectory: TrajectoryView, config: YawPlannerConfig) -> YawPlanner:
    """A planner in the exploring regime with ten past yaws in its window (1 s of calls at t_y)."""
    planner = YawPlanner(config)
    for k in range(10):
        t = -1.0 + k * config.period_s
        planner.plan(t, 0.02 * k, trajectory, snapshot, neighbours(t))
    return planner


def naive_ray_gains(snapshot: OccupancySnapshot, position: np.ndarray, azimuths: np.ndarray,
                    ranges: np.ndarray, covered: np.ndarray, areas: np.ndarray) -> np.ndarray:
    """The straightforward coverage: one ray at a time, one sample at a time, stop at the first occupied voxel."""
    nx, ny, nz = snapshot.shape
    kz = int((position[2] - snapshot.origin_world[2]) // snapshot.voxel_m)
    out = np.zeros(len(azimuths))
    for r, az in enumerate(azimuths):
        c, s = math.cos(az), math.sin(az)
        for rng_m, area in zip(ranges, areas):
            ix = int(math.floor((position[0] + rng_m * c - snapshot.origin_world[0]) / snapshot.voxel_m))
            iy = int(math.floor((position[1] + rng_m * s - snapshot.origin_world[1]) / snapshot.voxel_m))
            inside = 0 <= ix < nx and 0 <= iy < ny and 0 <= kz < nz
            state = int(snapshot.state[ix, iy, kz]) if inside else -1
            if state == 1:
                break
            if state == -1 and not (inside and covered[(ix + 1) * (ny + 2) + iy + 1]):
                out[r] += area
    return out


def naive_plan(planner: YawPlanner, yaw: float, trajectory: TrajectoryView, snapshot: OccupancySnapshot,
               time_s: float) -> np.ndarray:
    """Baseline exploring plan: every candidate's sector cast by the per-ray loop at every layer, same Dijkstra."""
    cfg, fan = planner.config, FanGeometry.from_config(planner.config)
    m, q, n = cfg.n_candidates, cfg.max_hop, cfg.n_steps
    times = time_s + np.arange(n + 1) * cfg.period_s
    positions = trajectory.positions(times)
    covered = past_coverage(snapshot, np.concatenate([p for _, p in planner._window]))
    e = np.zeros((n, m, 2 * q + 1))
    for i in range(1, n + 1):
        sector = {}
        for k in range(m):
            az = fan.azimuths(yaw + k * cfg.candidate_spacing_rad)[: fan.n_sector]
            sector[k] = naive_ray_gains(snapshot, positions[i], az, fan.ranges_m, covered, fan.areas_m2)
        for j in range(m):
            for h in range(-q, q + 1):
                # rays of k's sector outside j's: the strip swept by the turn
                shift = int(round((j + h) * fan.n_fan / m)) - int(round(j * fan.n_fan / m))
                g = sector[(j + h) % m]
                e[i - 1, j, h + q] = g[-shift:].sum() if shift > 0 else g[:-shift].sum() if shift < 0 else 0.0
    e /= float(np.max(np.abs([int(round((j + h) * fan.n_fan / m)) - int(round(j * fan.n_fan / m))
                               for j in range(m) for h in range(-q, q + 1)]))) * float(fan.areas_m2.sum())
    unseen = [p for p in neighbours(time_s) if time_s - p.stamp_s > cfg.t_hold_s]
    v = visibility_rewards(positions[1:], times[1:], yaw + np.arange(m) * cfg.candidate_spacing_rad, unseen, cfg)
    path = shortest_path(edge_costs(e, v, cfg.alpha, cfg.beta, cfg.turn_penalty))
    return yaw + cfg.candidate_spacing_rad * np.concatenate([[0.0], np.cumsum(path.hops)])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=300, help="timed calls of plan()")
    args = parser.parse_args()
    config = YawPlannerConfig()
    snapshot = forest_snapshot()
    trajectory = straight_line()
    time_s, yaw = 0.0, 0.2
    preds = neighbours(time_s)
    planner = warm_planner(snapshot, trajectory, config)
    plan = planner.plan(time_s, yaw, trajectory, snapshot, preds)
    assert plan.mode == "exploring", plan.mode
    window = list(planner._window)

    def one_plan() -> None:
        planner._window = type(planner._window)(window)  # same window every call
        planner.plan(time_s, yaw, trajectory, snapshot, preds)

    fast = median_ms(one_plan, args.repeats, warmup=5)
    print(f"yaw planner, exploring, {config.n_steps} layers x {config.n_candidates} candidates, "
          f"{len(preds)} neighbours ({plan.n_active - plan.n_recent} unseen), median of {args.repeats} calls")
    print(f"  plan(): {fast:7.2f} ms   goal <= 5 ms: {'met' if fast <= 5.0 else 'NOT met'}   "
          f"(S(0) = {plan.safety_margin_s:.2f} s, tau_s = {plan.safe_time_s:.2f} s, "
          f"yaw {plan.yaws[0]:+.2f} -> {plan.yaws[-1]:+.2f} rad)")
    # parts, on this plan's own inputs
    fan = FanGeometry.from_config(config)
    times = time_s + np.arange(1, config.n_steps + 1) * config.period_s
    positions = trajectory.positions(times)
    covered = past_coverage(snapshot, np.concatenate([p for _, p in window]))
    cast_ms = median_ms(lambda: cast_fans(snapshot, positions, fan.azimuths(yaw), fan.ranges_m), args.repeats)
    m, q = config.n_candidates, config.max_hop
    e, e_max = edge_gains(ray_gains(cast_fans(snapshot, positions, fan.azimuths(yaw), fan.ranges_m), covered,
                                    fan.areas_m2), fan, m, q)
    unseen = [p for p in preds if time_s - p.stamp_s > config.t_hold_s]
    v = visibility_rewards(positions, times, yaw + np.arange(m) * config.candidate_spacing_rad, unseen, config)
    cost = edge_costs(e / e_max, v, config.alpha, config.beta, config.turn_penalty)
    dijkstra_ms = median_ms(lambda: shortest_path(cost), args.repeats)
    print(f"  parts: fan cast ({config.n_steps} x {fan.n_fan} rays) {cast_ms:6.2f} ms   "
          f"Dijkstra ({shortest_path(cost).expanded} nodes expanded) {dijkstra_ms:6.2f} ms")
    # the other modes on the same scene: observing (every neighbour seen now), tracking (tau_thr raised above S(0))
    seen = [NeighborPrediction.constant_velocity(p.neighbor_id, p.source, time_s, p.position(time_s),
                                                 p.vel_world[0], p.cov_world) for p in preds]
    observing = warm_planner(snapshot, trajectory, config)
    assert observing.plan(time_s, yaw, trajectory, snapshot, seen).mode == "observing"
    observe_ms = median_ms(lambda: observing.plan(time_s, yaw, trajectory, snapshot, seen), args.repeats)
    slow_turns = type("SlowTurns", (YawPlannerConfig,), {"epsilon": 3.0})  # epsilon is a class constant
    tracking = YawPlanner(slow_turns(safety_horizon_s=6.0))
    assert tracking.plan(time_s, yaw, trajectory, snapshot, preds).mode == "tracking"
    track_ms = median_ms(lambda: tracking.plan(time_s, yaw, trajectory, snapshot, preds), args.repeats)
    print(f"  other modes: observing {observe_ms:6.2f} ms   tracking {track_ms:6.2f} ms")
    # the safety metric (Eq. 1) every mode pays: S(0) alone (what plan() computes) against the whole S(tau) profile
    # (what it computed before); a trajectory climbing 0.1 m/s crosses voxel layers as flown ones do, so its samples
    # fall in several altitude slabs, each a distance transform
    climb = TrajectoryView(
        position_at=lambda t: np.array([0.0, 0.0, ALTITUDE_M]) + (np.asarray(t)[:, None] - time_s) * np.array([SPEED_MPS, 0.0, 0.1]),
        velocity_at=lambda t: np.broadcast_to(np.array([SPEED_MPS, 0.0, 0.1]), (np.size(t), 3)).copy(),
        end_time_s=time_s + 3.0,
    )
    now_ms = median_ms(lambda: safety_margin(snapshot, climb, time_s, config, profile=False), args.repeats)
    profile_ms = median_ms(lambda: safety_margin(snapshot, climb, time_s, config), args.repeats)
    same = safety_margin(snapshot, climb, time_s, config, profile=False).margin_now_s == safety_margin(snapshot, climb, time_s, config).margin_now_s
    print(f"  safety metric: S(0) alone {now_ms:6.2f} ms   baseline, whole S(tau) profile {profile_ms:6.2f} ms   "
          f"ratio x{profile_ms / now_ms:.1f}   same S(0): {same}")
    # the denied agent's look before moving (denied.fresh_path_age_s), checked at the same t_y beside plan(): its
    # corridor over the default 1.3 m at 1 m/s, every voxel fresh, so no early exit (the most it costs)
    from mpcde.config.denied import DeniedAgentConfig
    from mpcde.onboard.denied.look import first_stale_point
    from planners.minco import minco_s3

    agent_cfg = DeniedAgentConfig(fresh_path_age_s=1.0)
    seen_snap = OccupancySnapshot(time_s, snapshot.origin_world, VOXEL_M, snapshot.state, snapshot.distance_m,
                                  snapshot.free_distance_m, np.zeros(snapshot.shape, np.float32))
    start, vel = np.array([0.0, 0.0, ALTITUDE_M]), np.array([SPEED_MPS, 0.0, 0.0])
    line = minco_s3(np.stack([start, vel, np.zeros(3)]), np.stack([start + 3.0 * vel, vel, np.zeros(3)]),
                    np.zeros((0, 3)), np.array([3.0]), t0_s=time_s)

    def check():
        return first_stale_point(seen_snap, line, time_s, max_age_s=agent_cfg.fresh_path_age_s,
                                 half_width_m=agent_cfg.fresh_path_half_width_m, near_m=agent_cfg.fresh_path_near_m,
                                 far_m=SPEED_MPS**2 / agent_cfg.limits.a_max_mps2 + agent_cfg.fresh_path_distance_m)

    assert check() is None
    fresh_ms = median_ms(check, args.repeats)
    print(f"  look before moving, corridor check: {fresh_ms:6.3f} ms   against plan() {fast:6.2f} ms   "
          f"ratio x{fresh_ms / fast:.3f}")
    # baseline: per-ray loop, measured in this run
    naive_cast_ms = median_ms(
        lambda: [naive_ray_gains(snapshot, p, fan.azimuths(yaw), fan.ranges_m, covered, fan.areas_m2)
                 for p in positions], 3)
    planner._window = type(planner._window)(window)
    naive = naive_plan(planner, yaw, trajectory, snapshot, time_s)
    planner._window = type(planner._window)(window)
    fast_yaws = planner.plan(time_s, yaw, trajectory, snapshot, preds).yaws
    naive_ms = median_ms(lambda: naive_plan(planner, yaw, trajectory, snapshot, time_s), 3, warmup=0)
    print(f"  baseline fan cast, per-ray Python loop: {naive_cast_ms:8.1f} ms   ratio x{naive_cast_ms / cast_ms:.0f}")
    print(f"  baseline plan, every sector cast by the per-ray loop: {naive_ms:8.1f} ms   ratio x{naive_ms / fast:.0f}"
          f"   same yaws: {bool(np.allclose(naive, fast_yaws))}")


if __name__ == "__main__":
    main()
