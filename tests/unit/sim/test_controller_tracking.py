"""The SE(3) controller flies the PyBullet quadrotor along a figure-eight."""

import numpy as np
import pytest

from sim.bullet.scene import SceneSpec
from sim.types import FlatOutputReference
from sim.world import World


def figure_eight(t: float, a: float = 3.0, b: float = 1.5, w: float = 0.687) -> FlatOutputReference:
    """Lissajous figure-eight at 1.5 m altitude; w chosen for a mean speed of 2 m/s."""
    p = np.array([a * np.sin(w * t), b * np.sin(2 * w * t), 1.5])
    v = np.array([a * w * np.cos(w * t), 2 * b * w * np.cos(2 * w * t), 0.0])
    acc = np.array([-a * w * w * np.sin(w * t), -4 * b * w * w * np.sin(2 * w * t), 0.0])
    return FlatOutputReference(pos_world=p, vel_world=v, acc_world=acc, yaw=0.0)


@pytest.mark.slow
def test_controller_tracks_a_figure_eight_at_2_mps_within_10_cm_rms():
    world = World(SceneSpec(obstacles=(), n_drones=1), np.array([[0.0, 0.0, 1.5]]), np.zeros(1))
    period = 2 * np.pi / 0.687
    errors, speeds = [], []
    try:
        while world.time_s < 2 * period:
            ref = figure_eight(world.time_s + world.dt_s)
            s = world.step([ref])
            if world.time_s > period:  # the second lap, after the take-off transient
                errors.append(np.linalg.norm(s.pos_world[0] - ref.pos_world))
                speeds.append(np.linalg.norm(s.vel_world[0]))
    finally:
        world.close()
    assert np.mean(speeds) == pytest.approx(2.0, abs=0.1)
    rms = float(np.sqrt(np.mean(np.square(errors))))
    assert rms < 0.1, f"RMS position error {rms:.3f} m"


def test_hover_settles_at_the_reference_and_heading():
    world = World(SceneSpec(obstacles=(), n_drones=1), np.array([[0.0, 0.0, 1.0]]), np.zeros(1))
    try:
        for _ in range(int(4 * 240)):
            s = world.step([FlatOutputReference.hover(np.array([0.5, -0.3, 1.5]), yaw=0.8)])
    finally:
        world.close()
    assert np.allclose(s.pos_world[0], [0.5, -0.3, 1.5], atol=0.02)
    yaw = np.arctan2(s.rotation_body_to_world[0, 1, 0], s.rotation_body_to_world[0, 0, 0])
    assert yaw == pytest.approx(0.8, abs=0.02)
    assert np.linalg.norm(s.vel_world[0]) < 0.02
