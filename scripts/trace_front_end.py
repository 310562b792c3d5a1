"""Trace one denied drone of a sweep's flight: its progress and front-end refusals, and dump a refused search.

Flies CELL:SEED of a sweep file with the package's own flight loop (the same flight ``mpcde sweep`` flies) and
prints, every ``--every`` seconds of simulated time, drone ``--drone``'s position, horizontal distance to its
goal, refused front-end searches by status, fallbacks and its two nearest neighbours (ground truth: this is
a diagnosis, not onboard data). With ``--dump T``, the first refused search at or after T seconds is printed
voxel by voxel, one horizontal slice per altitude layer the search may use: ``#`` occupied, ``?`` unknown,
``c`` inside the clearance band, ``.`` traversable, ``S`` the start, ``G`` the goal searched for.

Example (the long flight of docs/results/safety.md, "a goal cut off in a thin layer"):
    .venv/bin/python scripts/trace_front_end.py data/sweeps/forest_swarm_denied_levels.yaml 2:41 --drone 4 --until 37 --dump 5
"""

from __future__ import annotations

import argparse

import numpy as np

import mpcde.onboard.denied.agent as denied
from mpcde.flight.loop import open_session, prepare_run
from mpcde.sweep.spec import load_sweep
from perception.types import OccupancySnapshot


def dump_search(snap: OccupancySnapshot, start: np.ndarray, result, clearance_m: float, conf, t: float) -> None:
    """Print the layers of a refused search (module docstring)."""
    v = snap.voxel_m
    z = snap.origin_world[2] + v * (np.arange(snap.shape[2]) + 0.5)
    layers = np.nonzero((z >= conf.min_altitude_m) & (z <= conf.max_altitude_m))[0]
    s = snap.world_to_index(np.asarray(start)[None])[0]
    g = snap.world_to_index(np.asarray(result.goal_used_world)[None])[0]
    print(f"refused at t={t:.2f} s: {result.status}, start {np.round(start, 3).tolist()}, goal searched for "
          f"{np.round(result.goal_used_world, 3).tolist()} (clipped: {result.goal_clipped}), clearance {clearance_m} m, "
          f"window origin {np.round(snap.origin_world, 3).tolist()}, voxel {v} m, layers z = {np.round(z[layers], 3).tolist()}")
    state, dist = np.asarray(snap.state), np.asarray(snap.distance_m)
    for k in layers:
        print(f"layer z = {z[k]:.3f} m (rows: x index, columns: y index)")
        for i in range(snap.shape[0]):
            row = []
            for j in range(snap.shape[1]):
                ch = "#" if state[i, j, k] == OccupancySnapshot.OCCUPIED else "?" if state[i, j, k] == OccupancySnapshot.UNKNOWN else "c" if dist[i, j, k] < clearance_m else "."
                ch = "S" if (i, j) == (s[0], s[1]) else "G" if (i, j) == (g[0], g[1]) else ch
                row.append(ch)
            print("  " + "".join(row))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sweep")
    ap.add_argument("flight", help="CELL:SEED")
    ap.add_argument("--drone", type=int, required=True)
    ap.add_argument("--until", type=float, default=60.0, help="stop at this simulated time [s]")
    ap.add_argument("--every", type=float, default=0.5, help="print interval [s]")
    ap.add_argument("--dump", type=float, default=None, help="dump the first refused search at or after this time [s]")
    args = ap.parse_args()

    spec = load_sweep(args.sweep)
    cells = {c.index: c for c in spec.cells()}
    cell, seed = (int(x) for x in args.flight.split(":"))
    cfg = spec.scenario(cells[cell], seed)
    prepared = prepare_run(cfg)
    session = open_session(prepared)
    me, goal = session.agents[args.drone], prepared.goals[args.drone]
    now, dumped = [0.0], [args.dump is None]
    search = denied.search_path

    def spy(snap, start, goal_world, clearance_m, conf, goal_fallback=True):
        result = search(snap, start, goal_world, clearance_m, conf, goal_fallback=goal_fallback)
        if conf is me.search and not result.found and not dumped[0] and now[0] >= args.dump:
            dumped[0] = True
            dump_search(snap, start, result, clearance_m, conf, now[0])
        return result

    denied.search_path = spy
    try:
        last = -np.inf
        while not session.done:
            truth = session.step()
            now[0] = t = truth.time_s
            if t > args.until:
                break
            if t - last >= args.every - 1e-9:
                last = t
                p = truth.pos_world
                near = sorted((float(np.linalg.norm(p[j] - p[args.drone])), j) for j in range(len(p)) if j != args.drone)[:2]
                print(f"t={t:5.1f} s  pos ({p[args.drone][0]:6.2f}, {p[args.drone][1]:6.2f}, {p[args.drone][2]:5.2f})  "
                      f"to goal {np.linalg.norm(p[args.drone][:2] - goal[:2]):5.2f} m  refused {dict(me.stats.front_end_failures)}  "
                      f"fallbacks {me.stats.goal_fallbacks}  nearest {[(j, round(d, 2)) for d, j in near]}", flush=True)
    finally:
        session.close()  # render pool and shared memory


if __name__ == "__main__":
    main()
