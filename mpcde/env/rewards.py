"""The environments' default reward, and what a replacement reward is given.

Default (per drone i and control step, from the simulator's ground truth,
which a reward may read: it is the trainer's signal, not an observation):

    r_i = w_p (d_i(t0) - d_i(t1)) - c * collided_i + b * arrived_i

with d_i the true distance [m] to the goal at the step's start t0 and end t1
(progress toward the goal, negative when moving away), ``collided_i`` 1 when
the drone had a collision event in the step (another drone within 2 r_robot,
an obstacle or the ground touched; :class:`mpcde.flight.metrics.MetricsAccumulator`)
or its motors failed, and ``arrived_i`` 1 in the step it first came within
``run.goal_tolerance_m`` of its goal. Weights: ``progress_weight`` w_p,
``collision_penalty`` c, ``arrival_bonus`` b (:class:`mpcde.env.options.EnvOptions`).

A callable ``reward(outcome: StepOutcome) -> dict[str, float]`` replaces it
(``reward=`` of the environments); it gets one :class:`StepOutcome` per step.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["StepOutcome", "default_reward"]


@dataclass(frozen=True)
class StepOutcome:
    """One control step, for a reward.

    Attributes:
        agents: the agents that acted in the step (names).
        drone_index: agent name -> drone index.
        t0_s, t1_s: the step's start and end [s].
        pos_before, pos_after: (N, 3) true positions [m] at t0 and t1.
        goals: (N, 3) goals [m].
        collided: agent name -> whether it collided (or failed) in the step.
        arrived: agent name -> whether it first reached its goal in the step.
        events: the step's collision events (``metrics.json``'s ``collision_events`` format).
        progress_weight, collision_penalty, arrival_bonus: the options' weights.
    """

    agents: tuple[str, ...]
    drone_index: dict[str, int]
    t0_s: float
    t1_s: float
    pos_before: np.ndarray
    pos_after: np.ndarray
    goals: np.ndarray
    collided: dict[str, bool]
    arrived: dict[str, bool]
    events: tuple[dict, ...]
    progress_weight: float
    collision_penalty: float
    arrival_bonus: float


def default_reward(o: StepOutcome) -> dict[str, float]:
    """The module docstring's reward for every agent of the step."""
    out = {}
    for a in o.agents:
        i = o.drone_index[a]
        progress = float(np.linalg.norm(o.pos_before[i] - o.goals[i]) - np.linalg.norm(o.pos_after[i] - o.goals[i]))
        out[a] = o.progress_weight * progress - o.collision_penalty * float(o.collided[a]) + o.arrival_bonus * float(o.arrived[a])
    return out
