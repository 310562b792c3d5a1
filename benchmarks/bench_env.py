"""Benchmark: the learning environments' step rate, against ``mpcde fly`` and PyFlyt's multi-agent QuadX env.

Rows (6 drones of ``forest_swarm``, seed 0, random actions drawn from the
action space with a fixed seed; medians over ``--repeats`` episodes):

1. *No cameras*: :class:`mpcde.env.SwarmParallelEnv` (``cameras=False``,
   observation ``pose, goal, radio``, velocity actions, 25 Hz control over
   240 Hz physics), ``--steps`` env steps: env steps per second and simulated
   drone-steps per second (env steps x 6). Issue 30's goal: >= 2,000 drone-steps/s.
2. *PyFlyt peer*, when PyFlyt imports (``make bench-peer`` installs it):
   PyFlyt 0.29.0's ``MAQuadXHoverEnvV2`` (PettingZoo, 6 QuadX drones, 24 Hz
   agent rate, the nearest divisor of its 120 Hz loop to our 25 Hz), the same
   number of steps with random actions: the same two figures.
3. *Cameras, the same flight*: ``mpcde fly --mode denied`` (the baseline)
   against the env driven by :class:`mpcde.env.StackPolicy` (``denied``) at
   ``control_hz = 240`` with ``broadcast=False`` and ``copy_images=False`` (one
   image copy per frame, not per 240 Hz step), which flies the very same
   flight (tests/integration/test_env_policy.py): real-time factors and their
   ratio, env / fly. Issue 30's goal: within 10 %.
4. *Cameras, a 25 Hz learner*: the env with its default observation (pose,
   goal, camera, tracks: the detector and tracker run for every drone) and
   random velocity actions: env steps per second and real-time factor.

Run: ``.venv/bin/python benchmarks/bench_env.py [--quick]``
"""

from __future__ import annotations

import argparse
import contextlib
import io
import time

import numpy as np

import mpcde
from mpcde.env import StackPolicy, SwarmParallelEnv
from mpcde.env.policies import EXACT_REPLAY_OPTIONS



def random_steps(env, steps: int, seed: int) -> tuple[float, int]:
    """Wall time [s] of ``steps`` env steps with random actions (episodes restarted as they end) and the steps taken."""
    env.reset(seed=seed)
    for k, a in enumerate(env.possible_agents):
        env.action_space(a).seed(seed + k)
    done = 0
    t0 = time.perf_counter()
    while done < steps:
        if not env.agents:
            env.reset(seed=seed + done)
        env.step({a: env.action_space(a).sample() for a in env.agents})
        done += 1
    return time.perf_counter() - t0, done


def ours_without_cameras(steps: int, repeats: int) -> float:
    env = SwarmParallelEnv("forest_swarm", cameras=False, observe=("pose", "goal", "radio"))
    random_steps(env, 25, 0)  # warm-up
    rates = [s / w for w, s in (random_steps(env, steps, 0) for _ in range(repeats))]
    env.close()
    return float(np.median(rates))


def pyflyt_without_cameras(steps: int, repeats: int) -> float | str:
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            from PyFlyt.pz_envs import MAQuadXHoverEnvV2
    except Exception as e:  # not installed, or not importable with this numpy
        return f"skipped: PyFlyt does not import ({type(e).__name__}: {e}); `make bench-peer` installs it"
    from mpcde.flight.loop import prepare_run

    p = prepare_run(mpcde.load_scenario("forest_swarm"))
    yaw = np.arctan2(*(p.goals - p.starts)[:, 1::-1].T)
    with contextlib.redirect_stdout(io.StringIO()):
        env = MAQuadXHoverEnvV2(start_pos=p.starts, start_orn=np.column_stack([np.zeros((6, 2)), yaw]), agent_hz=24, max_duration_seconds=60.0, flight_dome_size=30.0)
        random_steps(env, 25, 0)
        rates = [s / w for w, s in (random_steps(env, steps, 0) for _ in range(repeats))]
    env.close()
    return float(np.median(rates))


def same_flight_with_cameras(duration_s: float, repeats: int) -> tuple[float, float]:
    """Median real-time factors of ``mpcde fly --mode denied`` and of the env flying it with the denied policy."""
    cfg = mpcde.load_scenario("forest_swarm", mode="denied", seed=0, duration_s=duration_s)
    fly_rtf, env_rtf = [], []
    mpcde.fly(cfg)  # warm-up: detector weights, numba kernels
    for _ in range(repeats):
        t0 = time.perf_counter()
        m = mpcde.fly(cfg).metrics
        fly_rtf.append(m["sim_time_s"] / (time.perf_counter() - t0))
        env = SwarmParallelEnv(cfg, options=EXACT_REPLAY_OPTIONS)
        policy = StackPolicy("denied", env)
        t0 = time.perf_counter()
        obs, _ = env.reset(seed=0)
        while env.agents:
            obs, *_ = env.step(policy(obs))
        sim = env.core.session.time_s
        env_rtf.append(sim / (time.perf_counter() - t0))
        env.close()
    return float(np.median(fly_rtf)), float(np.median(env_rtf))


def learner_with_cameras(steps: int, repeats: int) -> tuple[float, float]:
    env = SwarmParallelEnv("forest_swarm")
    random_steps(env, 10, 0)
    rates = [s / w for w, s in (random_steps(env, steps, 0) for _ in range(repeats))]
    env.close()
    rate = float(np.median(rates))
    return rate, rate / env.core.options.control_hz


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=500, help="env steps per timed episode without cameras")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--duration", type=float, default=6.0, help="simulated seconds of the camera flight [s]")
    ap.add_argument("--quick", action="store_true", help="fewer steps and a shorter camera flight")
    args = ap.parse_args()
    if args.quick:
        args.steps, args.repeats, args.duration = 200, 1, 2.0
    n = 6
    ours = ours_without_cameras(args.steps, args.repeats)
    print(f"no cameras, 6 drones, 25 Hz control: {ours:.0f} env steps/s = {n * ours:.0f} drone-steps/s (goal >= 2000)")
    peer = pyflyt_without_cameras(args.steps, args.repeats)
    if isinstance(peer, str):
        print(f"PyFlyt MAQuadXHoverEnvV2, 6 drones, 24 Hz: {peer}")
    else:
        print(f"PyFlyt MAQuadXHoverEnvV2, 6 drones, 24 Hz: {peer:.0f} env steps/s = {n * peer:.0f} drone-steps/s; ours / PyFlyt x{ours / peer:.2f}")
    fly_rtf, env_rtf = same_flight_with_cameras(args.duration, args.repeats)
    print(f"cameras, the same denied flight ({args.duration:g} s): mpcde fly RTF {fly_rtf:.3f}, env + denied policy at 240 Hz RTF {env_rtf:.3f}; env / fly x{env_rtf / fly_rtf:.3f} (goal >= 0.90)")
    rate, rtf = learner_with_cameras(max(50, args.steps // 4), args.repeats)
    print(f"cameras, 25 Hz learner (pose, goal, camera, tracks): {rate:.1f} env steps/s = {n * rate:.0f} drone-steps/s, RTF {rtf:.3f}")


if __name__ == "__main__":
    main()
