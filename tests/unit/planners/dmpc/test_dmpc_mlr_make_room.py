"""DMPC-Swarm's high-level planner (MlrConfig.make_room): deadlock detection and who makes room for whom."""

from __future__ import annotations

import numpy as np

from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.make_room import MakeRoomPlanner
from planners.dmpc.mlr.types import UavStateMessage
from planners.dmpc.mlr.uav import INITIAL_ID

# UAV 0 at the origin, 0.4 m from its goal; UAV 1 0.6 m in front of it, 2 m from its goal behind UAV 0;
# UAV 2 far away and 2 m from its goal.
POS = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 1.0], [2.5, 2.5, 1.0]])
GOALS = np.array([[0.4, 0.0, 1.0], [-1.4, 0.0, 1.0], [2.5, 0.5, 1.0]])


def _cfg(**kw) -> MlrConfig:
    return MlrConfig(n_uavs=3, n_cus=2, horizon_rounds=5, make_room=True, **kw)


def _states(k: int, pos: np.ndarray) -> dict[int, UavStateMessage]:
    return {i: UavStateMessage(i, k, pos[i], np.zeros(3), GOALS[i], INITIAL_ID) for i in range(3)}


def test_a_standing_swarm_is_a_deadlock_after_the_window_and_the_nearer_uav_makes_room() -> None:
    cfg = _cfg()
    planner = MakeRoomPlanner(cfg, POS, GOALS)
    for k in range(cfg.make_room_rounds):
        planner.observe(k, _states(k, POS))
        assert not planner.active  # the progress window is not full yet
        assert np.array_equal(planner.target(0, GOALS[0]), GOALS[0])
    planner.observe(cfg.make_room_rounds, _states(cfg.make_room_rounds, POS))
    assert planner.active and planner.detections == 1
    # UAV 0 is closer to its goal and lies on UAV 1's way to its goal: it gives way, UAV 1 does not
    assert planner.gives_way_to(0) == 1 and planner.gives_way_to(1) is None and planner.gives_way_to(2) is None
    target = planner.target(0, GOALS[0])
    offset = target - POS[0]
    assert abs(np.linalg.norm(offset - cfg.make_room_step_m * np.array([-1.0, 0.0, 0.0])) - cfg.make_room_noise_m) < 1e-9
    assert np.array_equal(planner.target(1, GOALS[1]), GOALS[1])
    # the same messages give the same target in another CU (seeded by the detection round)
    other = MakeRoomPlanner(cfg, POS, GOALS)
    for k in range(cfg.make_room_rounds + 1):
        other.observe(k, _states(k, POS))
    assert np.array_equal(other.target(0, GOALS[0]), target)


def test_progress_ends_the_deadlock_and_moving_uavs_never_start_one() -> None:
    cfg = _cfg()
    planner = MakeRoomPlanner(cfg, POS, GOALS)
    for k in range(cfg.make_room_rounds + 1):
        planner.observe(k, _states(k, POS))
    assert planner.active
    pos = POS.copy()
    k0 = cfg.make_room_rounds + 1
    active = []
    for k in range(k0, k0 + 4):
        pos[1, 1] += 0.1  # UAV 1 slides sideways: no progress to its goal
        pos[2, 1] -= 0.1  # UAV 2 flies to its goal at 0.5 m/s
        planner.observe(k, _states(k, pos))
        active.append(planner.active)
    # the mean progress of the three reaches 0.1 m when UAV 2 has covered about 0.3 m (its distances are not exact)
    assert active[:2] == [True, True] and active[-1] is False
    moving = MakeRoomPlanner(cfg, POS, GOALS)
    pos = POS.copy()
    for k in range(2 * cfg.make_room_rounds):
        step = GOALS - pos
        pos += 0.015 * step / np.linalg.norm(step, axis=1, keepdims=True)  # 0.15 m per window each
        moving.observe(k, _states(k, pos))
        assert not moving.active
