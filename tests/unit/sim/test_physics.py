"""Quadrotor physics: allocation, motors, forces through PyBullet, URDF consistency."""

import xml.etree.ElementTree as ET

import numpy as np
import pytest

from sim.bullet.scene import DRONE_URDF, SceneSpec
from sim.vehicle.motors import MotorBank, allocation_matrix
from sim.vehicle.params import GRAVITY_MPS2, QuadrotorParams
from sim.types import FlatOutputReference
from sim.world import World


def test_urdf_mass_and_inertia_match_the_parameters():
    link = ET.parse(DRONE_URDF).getroot().find("link")
    inertial = link.find("inertial")
    p = QuadrotorParams()
    assert float(inertial.find("mass").get("value")) == pytest.approx(p.mass_kg)
    I = inertial.find("inertia")
    assert [float(I.get(k)) for k in ("ixx", "iyy", "izz")] == pytest.approx(list(p.inertia_kgm2))


def test_platform_matches_mp_cde_thrust_to_weight():
    assert QuadrotorParams().thrust_to_weight == pytest.approx(4.2, abs=0.05)


def test_allocation_reproduces_the_wrench_it_was_asked_for():
    p = QuadrotorParams()
    bank = MotorBank(p, 3)
    wrench = np.array([[p.mass_kg * GRAVITY_MPS2, 0.01, -0.02, 0.003], [6.0, 0.0, 0.0, 0.0], [10.0, -0.05, 0.05, -0.01]])
    f = bank.thrusts_for_wrench(wrench)
    assert np.allclose(f @ allocation_matrix(p).T, wrench, atol=1e-9)


def test_saturation_sacrifices_yaw_before_thrust_and_tilt():
    p = QuadrotorParams()
    bank = MotorBank(p, 1)
    wrench = np.array([[4 * p.max_thrust_per_motor_n * 0.95, 0.0, 0.0, 0.5]])  # yaw torque far beyond reach
    f = bank.thrusts_for_wrench(wrench)
    achieved = f @ allocation_matrix(p).T
    assert np.all(f <= p.max_thrust_per_motor_n + 1e-12) and np.all(f >= 0)
    assert achieved[0, 0] == pytest.approx(wrench[0, 0])
    assert abs(achieved[0, 3]) < 0.5


def test_motor_lag_is_first_order():
    p = QuadrotorParams()
    bank = MotorBank(p, 1)
    w0 = bank.speed_radps.copy()
    target = np.full((1, 4), p.max_thrust_per_motor_n)
    dt = p.motor_time_constant_s  # one time constant
    bank.step(target, dt)
    expected = w0 + (p.motor_speed_max_radps - w0) * (1 - np.exp(-1.0))
    assert np.allclose(bank.speed_radps, expected)


def test_free_fall_with_motors_off_follows_gravity():
    world = World(SceneSpec(obstacles=(), n_drones=1), np.array([[0.0, 0.0, 20.0]]), np.zeros(1))
    world.fail_drone(0)
    world.motors.speed_radps[:] = 0.0
    try:
        for _ in range(120):  # 0.5 s
            s = world.step([FlatOutputReference.hover(np.zeros(3))])
    finally:
        world.close()
    # Bullet integrates semi-implicitly: v_{k+1} = v_k + a(v_k) dt, z_{k+1} = z_k + v_{k+1} dt,
    # with the body drag a = -g - (c / m) v_k; the same recursion, independently:
    m, c, g, dt = 0.8, QuadrotorParams().linear_drag_coeff, GRAVITY_MPS2, 1 / 240
    z, v = 20.0, 0.0
    for _ in range(120):
        v += (-g - c / m * v) * dt
        z += v * dt
    assert s.pos_world[0, 2] == pytest.approx(z, abs=1e-4)
    assert s.vel_world[0, 2] == pytest.approx(v, abs=1e-4)


def test_a_yaw_torque_turns_the_drone_the_right_way_even_when_tilted():
    world = World(SceneSpec(obstacles=(), n_drones=1), np.array([[0.0, 0.0, 2.0]]), np.zeros(1))
    try:
        for _ in range(240):
            s = world.step([FlatOutputReference(pos_world=np.array([0.0, 0.0, 2.0]), acc_world=np.array([3.0, 0.0, 0.0]), yaw=0.5)])
    finally:
        world.close()
    yaw = np.arctan2(s.rotation_body_to_world[0, 1, 0], s.rotation_body_to_world[0, 0, 0])
    assert yaw == pytest.approx(0.5, abs=0.05)
