"""The environments with cameras, and the package's stacks as policies (slow: real flights with rendering)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test

import mpcde
from mpcde.env import SingleDroneEnv, StackPolicy, SwarmParallelEnv
from mpcde.env.policies import EXACT_REPLAY_OPTIONS
from mpcde.sweep.store import WALL_CLOCK_KEYS

pytestmark = pytest.mark.slow



def test_the_denied_policy_flies_the_flight_of_mpcde_fly():
    """Same seed: the env driven by the denied policy gives the states and metrics of `mpcde fly --mode denied`,
    in an episode after another one (cut short mid-flight), whose render pool it takes over (a reset loads the new
    scene into the running render workers: sim/rendering/pool_keeper.py)."""
    cfg = mpcde.load_scenario("forest_swarm", mode="denied", seed=3, duration_s=2.5)
    fly = mpcde.fly(cfg)
    env = SwarmParallelEnv(cfg, options=EXACT_REPLAY_OPTIONS)
    before = StackPolicy("denied", env)
    obs, _ = env.reset(seed=1)  # another forest layout
    for _ in range(7):
        obs, *_ = env.step(before(obs))
    policy = StackPolicy("denied", env)
    obs, _ = env.reset(seed=3)
    assert (env.core.pools.started, env.core.pools.reloaded) == (1, 1)
    while env.agents:
        obs, *_ = env.step(policy(obs))
    flown = env.flight_result()
    env.close()
    for key, a in fly.log.arrays.items():
        assert np.array_equal(a, flown.log.arrays[key]), key
    # wall clock; `agents` holds each stack's own planner statistics; `render_workers` is how the run was executed
    # (fly leaves the mapping stack a core, the env cannot know its policy maps), and frames do not depend on it
    timing = set(WALL_CLOCK_KEYS) | {"agents", "render_workers"}
    a = {k: v for k, v in fly.metrics.items() if k not in timing}
    b = {k: v for k, v in flown.metrics.items() if k not in timing}
    assert a == b
    assert a["frames_received"] > 0 and a["tracking_pos_rmse_m"] is not None


def test_parallel_api_with_cameras_and_every_observation():
    env = SwarmParallelEnv("forest_swarm", observe=("pose", "goal", "camera", "detections", "tracks", "radio"), duration_s=1.2)
    parallel_api_test(env, num_cycles=1000)
    env.close()


def test_a_learner_among_five_mp_cde_drones_passes_check_env():
    env = SingleDroneEnv("forest_swarm", neighbours="denied", duration_s=1.0, render_mode="rgb_array")
    check_env(env)
    obs, _ = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    env.close()


def test_the_comm_policy_flies_the_crossing_over_the_env_radio():
    # plain DMPC: the env broadcasts each learner's held action as a plan, which does not halt, so the
    # committing comm stack's promise (dmpc.commit_when_unheard) does not carry over to the env's radio
    cfg = mpcde.load_scenario("crossing", mode="comm", duration_s=14.0)
    cfg = replace(cfg, dmpc=cfg.dmpc.replanning())
    env = SwarmParallelEnv(cfg, cameras=False, action="reference", observe=("pose", "goal", "radio"))
    policy = StackPolicy("comm", env)
    obs, _ = env.reset(seed=0)
    heard = 0
    while env.agents:
        heard += int(obs["drone_0"]["radio"]["valid"].sum()) if "drone_0" in obs else 0
        obs, rewards, terminated, truncated, infos = env.step(policy(obs))
    m = env.flight_result().metrics
    env.close()
    assert heard > 0
    assert m["collisions"] == 0 and m["arrived"] == 2
