"""Step the swarm as a PettingZoo env: random actions without cameras, then MP-CDE (the ``denied`` stack) as the policy.

Run: ``.venv/bin/python examples/env_random_and_denied.py`` (the ``env`` extra:
pettingzoo, gymnasium; ``scripts/setup.sh`` installs it). Trains nothing: it
shows the loop a learner would run. The README's ten lines are this file.
"""

from __future__ import annotations

from mpcde.env import StackPolicy, SwarmParallelEnv


def main(duration_s: float = 3.0) -> dict:
    """Both episodes of ``forest_swarm``; return the denied episode's metrics (those ``mpcde fly`` writes)."""
    env = SwarmParallelEnv("forest_swarm", cameras=False, observe=("pose", "goal"), duration_s=duration_s)
    obs, infos = env.reset(seed=0)
    while env.agents:  # random world-frame velocity + yaw rate per drone, 25 steps per second
        obs, rewards, terminated, truncated, infos = env.step({a: env.action_space(a).sample() for a in env.agents})
    env.close()
    env = SwarmParallelEnv("forest_swarm", action="reference", observe=("pose", "goal", "camera", "detections", "tracks"), duration_s=duration_s)
    policy = StackPolicy("denied", env)  # MP-CDE flying each drone from its own observation
    obs, infos = env.reset(seed=0)
    while env.agents:
        obs, rewards, terminated, truncated, infos = env.step(policy(obs))
    m = env.flight_result().metrics
    env.close()
    print(f"denied policy, {duration_s:g} s: collisions {m['collisions']}, min inter-drone {m['min_inter_drone_distance_m']:.2f} m, "
          f"tracking RMSE {m['tracking_pos_rmse_m']} m")
    return m


if __name__ == "__main__":
    main()
