"""The learning environments: PettingZoo and Gymnasium conformance, spaces, actions, rewards, terminations."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from pettingzoo.test import parallel_api_test, parallel_seed_test

from mpcde.env import ENV_ID, EnvOptions, SingleDroneEnv, SwarmParallelEnv
from mpcde.errors import ConfigError


def toward_goal(obs: dict, speed: float) -> np.ndarray:
    """A velocity action straight at the goal (from the drone's own estimate)."""
    d = obs["goal"] - obs["pose"]["pos_world"]
    v = speed * d / max(float(np.linalg.norm(d)), 1e-9)
    return np.r_[v, 0.0]


def test_parallel_api_without_cameras():
    env = SwarmParallelEnv("forest_swarm", cameras=False, observe=("pose", "goal", "radio"), duration_s=12.0)
    parallel_api_test(env, num_cycles=1000)
    env.close()


def test_parallel_seed_test_without_cameras():
    parallel_seed_test(lambda: SwarmParallelEnv("forest_swarm", cameras=False, observe=("pose", "goal", "radio"), duration_s=2.0), num_cycles=50)


def test_single_drone_env_passes_check_env_and_is_registered():
    env = gymnasium.make(ENV_ID, scenario="crossing", neighbours="placeholder", cameras=False, observe=("pose", "goal", "radio"), duration_s=2.0)
    assert isinstance(env.unwrapped, SingleDroneEnv)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_same_seed_same_episode_other_seed_other_world():
    def episode(seed: int) -> list[np.ndarray]:
        env = SwarmParallelEnv("forest_swarm", cameras=False, observe=("pose", "goal"), duration_s=1.0)
        obs, _ = env.reset(seed=seed)
        out = [obs["drone_0"]["pose"]["pos_world"]]
        while env.agents:
            obs, *_ = env.step({a: toward_goal(o, 1.0) for a, o in obs.items()})
            out.append(obs["drone_3"]["pose"]["pos_world"])
        env.close()
        return out

    a, b, c = episode(5), episode(5), episode(6)
    assert all(np.array_equal(x, y) for x, y in zip(a, b))
    assert not all(np.array_equal(x, y) for x, y in zip(a, c))


def test_observations_lie_in_their_spaces_with_every_entry():
    observe = ("pose", "goal", "camera", "detections", "tracks", "radio")
    env = SwarmParallelEnv("crossing", observe=observe, duration_s=0.6)
    obs, _ = env.reset(seed=0)
    space = env.observation_space("drone_0")
    assert set(space.spaces) == {"time_s", *observe}
    seen_frame = False
    while env.agents:
        for a, o in obs.items():
            assert space.contains(o), a
        seen_frame |= obs["drone_0"]["camera"]["time_s"][0] >= 0
        obs, *_ = env.step({a: toward_goal(o, 1.0) for a, o in obs.items()})
    assert seen_frame
    cam = obs["drone_0"]["camera"]
    assert cam["rgb"].shape == (240, 320, 3) and cam["depth_m"].dtype == np.float32
    assert (cam["depth_m"] == 0).any() or (cam["depth_m"] >= 0.2).all()  # 0 marks invalid depth, valid depth >= depth_min_m
    frame = env.render() if env.render_mode else None
    assert frame is None
    env.close()


def test_render_returns_the_video_frame():
    env = SwarmParallelEnv("crossing", cameras=False, observe=("pose",), render_mode="rgb_array", duration_s=0.2)
    env.reset(seed=0)
    img = env.render()
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[0] % 16 == 0 and img.shape[1] > img.shape[0]
    env.close()


def test_invalid_actions_raise_one_line_or_are_clipped_and_reported():
    env = SwarmParallelEnv("crossing", cameras=False, observe=("pose", "goal"), duration_s=1.0)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"^actions\['drone_0'\]\[1\] \(vy\)=nan: a number in \[-3, 3\]$"):
        env.step({"drone_0": np.array([0.0, np.nan, 0.0, 0.0]), "drone_1": np.zeros(4)})
    with pytest.raises(ValueError, match=r"^actions\['drone_1'\]\[3\] \(yaw_rate\)=9\.0: a number in "):
        env.step({"drone_0": np.zeros(4), "drone_1": np.array([0.0, 0.0, 0.0, 9.0])})
    with pytest.raises(ValueError, match=r"shape \(3,\), expected \(4,\)"):
        env.step({"drone_0": np.zeros(3)})
    with pytest.raises(ValueError, match="not an agent"):
        env.step({"drone_7": np.zeros(4)})
    env.close()
    env = SwarmParallelEnv("crossing", cameras=False, observe=("pose", "goal"), duration_s=1.0, invalid_action="clip")
    obs, _ = env.reset(seed=0)
    _, _, _, _, infos = env.step({"drone_0": np.array([50.0, 0.0, 0.0, 0.0]), "drone_1": np.array([np.nan] * 4)})
    assert infos["drone_0"]["action_clipped"] and infos["drone_1"]["action_clipped"]
    np.testing.assert_allclose(env.core.drones["drone_0"].hold.action, [3.0, 0.0, 0.0, 0.0])
    assert env.core.drones["drone_1"].hold.action is None  # NaN: hover where it estimates it is
    _, _, _, _, infos = env.step({"drone_0": np.zeros(4), "drone_1": np.zeros(4)})
    assert not infos["drone_0"]["action_clipped"]
    env.close()


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"action": "thrust"}, "env.action='thrust': one of velocity, reference"),
        ({"observe": ("pose", "lidar")}, "env.observe=('pose', 'lidar'): a non-empty list of pose, goal, camera, detections, tracks, radio"),
        ({"cameras": False, "observe": ("camera",)}, "env.observe=('camera',): camera only with cameras (env.cameras: true)"),
        ({"control_hz": 0.0}, "env.control_hz=0.0: a number in [1, 1000]"),
        ({"track_slots": 2**40}, "env.track_slots=1099511627776: an integer in [1, 64]"),
        ({"max_speed_mps": float("inf")}, "env.max_speed_mps=inf: a number in [0.1, 20]"),
    ],
)
def test_bad_options_are_refused_in_one_line(kwargs, message):
    with pytest.raises(ConfigError) as e:
        EnvOptions(**kwargs)
    assert str(e.value) == message


def test_the_defaults_follow_cameras_false_instead_of_refusing_it():
    """Observations without camera entries, neighbours on the radio: both envs build with cameras=False alone."""
    swarm = SwarmParallelEnv("crossing", cameras=False, duration_s=1.0)
    assert swarm.core.options.observe == ("pose", "goal")
    obs, _ = swarm.reset(seed=0)
    assert set(obs["drone_0"]) == {"time_s", "pose", "goal"}
    single = SingleDroneEnv("crossing", cameras=False, duration_s=1.0)
    assert single.core.cfg.planner.kind == "dmpc" and single.core.options.observe == ("pose", "goal")
    assert SwarmParallelEnv("crossing", duration_s=1.0).core.options.observe == ("pose", "goal", "camera", "tracks")
    with pytest.raises(ConfigError, match=r"^env\.neighbours='denied': a stack that flies without cameras"):
        SingleDroneEnv("crossing", neighbours="denied", cameras=False)
    with pytest.raises(ConfigError, match=r"^env\.observe=.*only with cameras"):
        SwarmParallelEnv("crossing", cameras=False, observe=("pose", "camera"))


def test_bad_environment_arguments_are_refused_before_a_world_is_built():
    with pytest.raises(ConfigError, match=r"^env\.neighbours='mlr': one of placeholder, denied, mpcde_paper, comm, auto, minco_comm$"):
        SingleDroneEnv("crossing", neighbours="mlr")
    with pytest.raises(ConfigError, match=r"^env\.learners=\[5\]: distinct drone indices in \[0, 1\]$"):
        SingleDroneEnv("crossing", neighbours="placeholder", learner=5, cameras=False, observe=("pose",))
    with pytest.raises(ConfigError, match=r"^env\.colour=1: a field of EnvOptions"):
        SwarmParallelEnv("crossing", options={"colour": 1})
    with pytest.raises(ConfigError, match=r"^scenario="):
        SwarmParallelEnv("no_such_scenario")


def test_arrival_terminates_with_the_bonus_and_the_reward_is_progress():
    env = SingleDroneEnv("crossing", neighbours="placeholder", cameras=False, observe=("pose", "goal"), duration_s=8.0)
    obs, _ = env.reset(seed=0)
    total, steps = 0.0, 0
    start = np.linalg.norm(obs["goal"] - obs["pose"]["pos_world"])
    while True:
        obs, r, terminated, truncated, info = env.step(toward_goal(obs, 2.0))
        total, steps = total + r, steps + 1
        if terminated or truncated:
            break
    assert terminated and not truncated and info["arrived"] and not info["collision_events"]
    # the progress terms telescope: start distance - distance at arrival (<= the 0.3 m tolerance), plus the bonus
    final = env.core.session.truth.pos_world[0]
    expected = start - np.linalg.norm(final - env.core.prepared.goals[0]) + 10.0
    assert total == pytest.approx(expected, abs=0.1)
    assert 3.5 < steps / 25.0 < 5.0  # 8 m at 2 m/s, with the take-off transient
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(4))
    env.close()


def test_collision_terminates_both_with_the_penalty_and_the_event():
    env = SwarmParallelEnv("crossing", cameras=False, observe=("pose", "goal"), duration_s=6.0, reward=None)
    obs, _ = env.reset(seed=0)
    while env.agents:
        obs, rewards, terminated, truncated, infos = env.step({a: toward_goal(o, 2.0) for a, o in obs.items()})
        if any(terminated.values()):
            break
    assert terminated == {"drone_0": True, "drone_1": True} and env.agents == []
    assert all(r < -9.0 for r in rewards.values())
    assert infos["drone_0"]["collision_events"][0]["kind"] == "drone"
    m = env.flight_result().metrics
    assert m["drone_drone_collisions"] == 1 and 1.8 < m["sim_time_s"] < 2.6
    env.close()


def test_a_reward_callable_replaces_the_default():
    seen = []

    def reward(outcome):
        seen.append(outcome)
        return {a: 1.0 for a in outcome.agents}

    env = SwarmParallelEnv("crossing", cameras=False, observe=("pose",), duration_s=0.2, reward=reward)
    env.reset(seed=0)
    _, rewards, *_ = env.step({})
    assert rewards == {"drone_0": 1.0, "drone_1": 1.0}
    assert seen[0].t1_s > seen[0].t0_s and seen[0].pos_before.shape == (2, 3)
    env.close()


def test_truncated_at_the_time_limit():
    env = SwarmParallelEnv("crossing", cameras=False, observe=("pose",), duration_s=0.4, control_hz=10.0)
    env.reset(seed=0)
    steps = 0
    while env.agents:
        _, _, terminated, truncated, _ = env.step({})
        steps += 1
    assert steps == 4 and all(truncated.values()) and not any(terminated.values())
    env.close()
