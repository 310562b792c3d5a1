"""The denied agent turns its own detections into tracks and plans around them (no flight, synthetic frames)."""

from dataclasses import replace

import numpy as np
import pytest

from mpcde.config.denied import DeniedAgentConfig
from mpcde.config.perception import PerceptionConfig
from mpcde.onboard.denied import DeniedAgent
from perception.types import Detection
from sim.camera import CameraConfig, intrinsics
from sim.types import PoseEstimate, RgbdFrame

START = np.array([0.0, 0.0, 1.5])
GOAL = np.array([6.0, 0.0, 1.5])
NEIGHBOUR = np.array([3.0, 0.0, 1.5])  # hovering on the straight line to the goal
CAM = CameraConfig()
K = intrinsics(CAM)
# camera optical frame (x right, y down, z forward) of a level drone heading +x
R_CW = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _frame(t: float) -> tuple[RgbdFrame, list[Detection]]:
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R_CW, START
    depth = np.full((CAM.height_px, CAM.width_px), np.nan, np.float32)  # nothing in range but the neighbour
    p_cam = R_CW.T @ (NEIGHBOUR - START)
    u, v = K[0, 0] * p_cam[0] / p_cam[2] + K[0, 2], K[1, 1] * p_cam[1] / p_cam[2] + K[1, 2]
    half = 0.5 * K[0, 0] * 0.18 / p_cam[2]  # a 0.18 m wide drone
    box = np.array([u - half, v - 0.4 * half, u + half, v + 0.4 * half])
    depth[int(box[1]) : int(box[3]) + 1, int(box[0]) : int(box[2]) + 1] = p_cam[2] - 0.05
    rgb = np.zeros((CAM.height_px, CAM.width_px, 3), np.uint8)
    return RgbdFrame(0, t, rgb, depth, K, T), [Detection(box, 0.9)]


def _fly_frames(config: DeniedAgentConfig) -> DeniedAgent:
    agent = DeniedAgent(0, GOAL, config)
    for k in range(15):
        t = 0.6 + 0.04 * k  # after the start delay, 25 Hz
        agent.on_pose_estimate(PoseEstimate(t, START, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3)))
        agent.on_frame(*_frame(t))
    return agent


def _closest_approach(agent: DeniedAgent) -> float:
    traj = agent.trajectory
    tau = np.linspace(0.0, traj.total_duration, 400)
    return float(np.min(np.linalg.norm(traj.pos(tau) - NEIGHBOUR, axis=1)))


def test_a_detected_neighbour_becomes_a_track_and_the_plan_keeps_the_swarm_clearance_from_it():
    agent = _fly_frames(DeniedAgentConfig())
    preds = agent.perception.predictions(agent.latest_estimate.time_s)
    assert len(preds) == 1
    np.testing.assert_allclose(preds[0].pos_world[0], NEIGHBOUR, atol=0.1)  # back-projected through the box's depth
    assert agent.stats.replans >= 1
    assert _closest_approach(agent) >= 0.9 * agent.config.swarm_clearance_m


def test_blind_to_neighbours_the_same_agent_plans_straight_through_it():
    agent = _fly_frames(replace(DeniedAgentConfig(), perceive_neighbours=False))
    assert agent.perception is None and agent.detector_request is None
    assert _closest_approach(agent) < 0.2  # the test above means something only if this plan would collide


def test_the_conflict_trigger_fires_for_a_neighbour_on_a_collision_course_only():
    agent = _fly_frames(replace(DeniedAgentConfig(), perceive_neighbours=False))
    t = agent.latest_estimate.time_s
    from perception.types import NeighborPrediction

    head_on = NeighborPrediction.constant_velocity(1, "perception", t, NEIGHBOUR - [1.5, 0.0, 0.0], np.array([-1.0, 0.0, 0.0]), np.zeros((6, 6)))
    aside = NeighborPrediction.constant_velocity(2, "perception", t, NEIGHBOUR + [0.0, 3.0, 0.0], np.zeros(3), np.zeros((6, 6)))
    assert agent._swarm_conflict(agent.trajectory, [head_on], t)
    assert not agent._swarm_conflict(agent.trajectory, [aside], t)


@pytest.mark.parametrize("field, value", [("swarm_clearance_m", -0.1), ("conflict_horizon_s", 0.0), ("swarm_z_scale", 0.5)])
def test_invalid_settings_are_refused_with_the_field_name(field, value):
    with pytest.raises(ValueError, match=f"^{field}="):
        DeniedAgentConfig(**{field: value})


def test_invalid_detector_threshold_is_refused_with_the_field_name():
    with pytest.raises(ValueError, match="^detector_score_threshold="):
        PerceptionConfig(detector_score_threshold=1.5)
