"""Benchmark: an environment's ``reset`` with the render pool kept across episodes, against a new pool per episode.

A reset starts a flight. With cameras, a flight needs render workers, and
each worker is a spawned process that imports the renderer and loads the
detector. Since the environments keep one pool
(:class:`sim.rendering.pool_keeper.PoolKeeper`), a reset loads the new
episode's scene into the running workers instead. The baseline, measured in
the same run, is a keeper with ``reuse=False``: every reset closes the pool
and starts a new one, as every reset did before.

Rows (``forest_swarm``, 6 drones, seeds drawn by the env from seed 0; median
wall time of ``reset()`` over ``--repeats`` resets, each after ``--steps``
steps with random actions, so the pool has a batch to hand over):

1. :class:`mpcde.env.SingleDroneEnv`, one learner among five MP-CDE drones
   (their detector runs in the render workers);
2. :class:`mpcde.env.SwarmParallelEnv`, six learners, its default observation
   (pose, goal, camera, tracks).

Run: ``.venv/bin/python benchmarks/bench_env_reset.py [--repeats N] [--quick]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from mpcde.env import SingleDroneEnv, SwarmParallelEnv
from sim.rendering.pool_keeper import PoolKeeper


def reset_ms(make_env, reuse: bool, repeats: int, steps: int) -> float:
    """Median wall time [ms] of ``reset()`` over ``repeats`` resets of one env, after a first (untimed) one."""
    env = make_env()
    env.unwrapped.core.pools = PoolKeeper(reuse=reuse)
    env.reset(seed=0)
    times = []
    parallel = isinstance(env, SwarmParallelEnv)
    for _ in range(repeats):
        for _ in range(steps):
            if parallel:
                env.step({a: env.action_space(a).sample() for a in env.agents})
            else:
                env.step(env.action_space.sample())
        t0 = time.perf_counter()
        env.reset()
        times.append(time.perf_counter() - t0)
    pools = env.unwrapped.core.pools
    assert (pools.started, pools.reloaded) == ((1, repeats) if reuse else (repeats + 1, 0))
    env.close()
    return 1e3 * float(np.median(times))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5, help="timed resets per row and setting")
    ap.add_argument("--steps", type=int, default=3, help="env steps before each timed reset")
    ap.add_argument("--quick", action="store_true", help="the first row only, one timed reset each way (the test suite's run)")
    args = ap.parse_args()
    if args.quick:
        args.repeats, args.steps = 1, 1
    rows = [
        ("SingleDroneEnv, a learner among 5 MP-CDE drones", lambda: SingleDroneEnv("forest_swarm", neighbours="denied", duration_s=5.0)),
        ("SwarmParallelEnv, 6 learners, camera + tracks", lambda: SwarmParallelEnv("forest_swarm", duration_s=5.0)),
    ]
    for name, make_env in rows[:1] if args.quick else rows:
        new = reset_ms(make_env, False, args.repeats, args.steps)
        kept = reset_ms(make_env, True, args.repeats, args.steps)
        print(f"{name}: reset median {kept:.0f} ms with the pool kept, {new:.0f} ms with a new pool per episode (baseline); x{new / kept:.1f} faster")


if __name__ == "__main__":
    main()
