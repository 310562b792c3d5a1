"""The physics world: PyBullet DIRECT client, ground, obstacles, N quadrotors.

Each physics tick (default 240 Hz) the SE(3) controller turns each drone's
reference into a wrench, the motor bank allocates it to four rotor thrusts
(saturated, with motor lag), and the thrusts are applied as forces at the rotor
hubs (as their exact resultant force and torque about the centre of mass),
the rotor drag torques and body drag through PyBullet; then PyBullet
integrates the rigid bodies. No pose is ever set by hand after spawning.

The controller reads the *true* state (it stands for the flight controller's
own fast state estimate); onboard planning reads the VIO-like pose estimate of
:mod:`sim.pose_estimate` instead.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from sim.bullet import pb
from sim.bullet.scene import SceneSpec, build_obstacles, load_drones
from sim.ground_truth import TrueState
from sim.rotations import quat_xyzw_from_yaw
from sim.types import FlatOutputReference
from sim.vehicle.controller import SE3Controller
from sim.vehicle.motors import MotorBank
from sim.vehicle.params import GRAVITY_MPS2
from sim.vehicle.rigid_body_kernels import motor_wrench_to_body_loads, rotations_and_body_rates
from sim.vehicle.physics_config import PhysicsConfig

__all__ = ["PhysicsConfig", "World"]


class World:
    """A headless PyBullet world; one verb, :meth:`step`.

    Args:
        spec: obstacles and drone model.
        start_pos_world: (N, 3) spawn positions [m].
        start_yaw: (N,) spawn headings [rad].
        config: physics settings.
    """

    def __init__(self, spec: SceneSpec, start_pos_world: np.ndarray, start_yaw: np.ndarray, config: PhysicsConfig | None = None) -> None:
        self.spec = spec
        self.config = config or PhysicsConfig()
        self.params = self.config.quadrotor
        n = spec.n_drones
        self.dt_s = 1.0 / self.config.physics_hz
        self.client = pb.connect(pb.DIRECT)
        pb.setGravity(0, 0, -GRAVITY_MPS2, physicsClientId=self.client)
        pb.setTimeStep(self.dt_s, physicsClientId=self.client)
        plane = pb.createCollisionShape(pb.GEOM_PLANE, physicsClientId=self.client)
        self.ground_id = pb.createMultiBody(0.0, plane, -1, physicsClientId=self.client)
        self.obstacle_ids = build_obstacles(self.client, spec.obstacles, with_collision=True)
        quats = np.stack([quat_xyzw_from_yaw(float(y)) for y in np.asarray(start_yaw, float)])
        self.drone_ids = load_drones(self.client, spec, np.asarray(start_pos_world, float), quats, fixed=False)
        for b in self.drone_ids:
            # aerodynamics are ours (body drag below); no artificial damping
            pb.changeDynamics(b, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=self.client)
        self._static_ids = set(self.obstacle_ids) | {self.ground_id}
        self._drone_index = {b: i for i, b in enumerate(self.drone_ids)}
        self.controller = SE3Controller(self.params, n, self.config.gains)
        self.motors = MotorBank(self.params, n)
        self.failed = np.zeros(n, bool)
        self.time_s = 0.0
        self.step_count = 0
        self._rotor_pos_body = np.ascontiguousarray(self.params.rotor_pos_body, float)
        self._motor_dirs = np.asarray(self.params.motor_dirs, float)
        tau_m = self.params.motor_time_constant_s
        self._lag_alpha = float(1.0 - np.exp(-self.dt_s / tau_m)) if tau_m > 0 else 1.0
        self._state = self._read_state()

    @property
    def n_drones(self) -> int:
        """Number of drones."""
        return self.spec.n_drones

    def close(self) -> None:
        """Disconnect the PyBullet client."""
        if self.client is not None and pb.isConnected(self.client):
            pb.disconnect(self.client)
        self.client = None

    def true_state(self) -> TrueState:
        """Ground truth after the latest tick (metrics and labels only)."""
        return self._state

    def fail_drone(self, index: int) -> None:
        """Cut a drone's motors (a scheduled fault or a crash); it falls."""
        self.failed[index] = True
        self.motors.enabled[index] = False

    def _read_state(self) -> TrueState:
        n = self.n_drones
        pos, quat, vel, omega_w = np.empty((n, 3)), np.empty((n, 4)), np.empty((n, 3)), np.empty((n, 3))
        c = self.client
        for i, b in enumerate(self.drone_ids):
            p, q = pb.getBasePositionAndOrientation(b, physicsClientId=c)
            v, w = pb.getBaseVelocity(b, physicsClientId=c)
            pos[i], quat[i], vel[i], omega_w[i] = p, q, v, w
        R, omega_b = rotations_and_body_rates(quat, omega_w)  # R(q), Omega_body = R^T omega_world
        contact = np.zeros(n, bool)
        for cp in pb.getContactPoints(physicsClientId=c):  # every contact of the world in one call
            a, b = cp[1], cp[2]
            if a in self._drone_index and b in self._static_ids:
                contact[self._drone_index[a]] = True
            elif b in self._drone_index and a in self._static_ids:
                contact[self._drone_index[b]] = True
        return TrueState(
            time_s=self.time_s,
            pos_world=pos,
            vel_world=vel,
            quat_xyzw=quat,
            rotation_body_to_world=R,
            ang_vel_body=omega_b,
            obstacle_contact=contact,
            failed=self.failed.copy(),
        )

    def step(self, references: Sequence[FlatOutputReference]) -> TrueState:
        """Advance one physics tick with each drone tracking its reference.

        Args:
            references: one :class:`FlatOutputReference` per drone.

        Returns:
            The true state after the tick.
        """
        s = self._state
        ref_p = np.stack([r.pos_world for r in references])
        ref_v = np.stack([r.vel_world for r in references])
        ref_a = np.stack([r.acc_world for r in references])
        ref_yaw = np.array([r.yaw for r in references], float)
        ref_yaw_rate = np.array([r.yaw_rate for r in references], float)
        wrench = self.controller.step(
            s.pos_world, s.vel_world, s.rotation_body_to_world, s.ang_vel_body, ref_p, ref_v, ref_a, ref_yaw, ref_yaw_rate, self.dt_s
        )
        # The four rotor thrusts f_i act along body z at the hubs r_i; their resultant
        # about the centre of mass is exactly F = sum_i f_i R e3 and
        # tau = R (sum_i r_i x f_i e3 + sum_i s_i k_m w_i^2 e3) (rotor drag torques), applied
        # as one force at the COM and one torque (2 PyBullet calls per drone instead of 6).
        # Compiled with the motors' allocation and lag (sim/vehicle/rigid_body_kernels.py).
        mb, p = self.motors, self.params
        force_world, torque_world = motor_wrench_to_body_loads(
            wrench, mb.A_inv, float(mb.f_max), mb.speed_radps, mb.enabled, float(p.thrust_coeff), float(p.torque_coeff),
            self._motor_dirs, self._lag_alpha, self._rotor_pos_body, s.rotation_body_to_world, s.vel_world, float(p.linear_drag_coeff),
        )  # fmt: skip
        c = self.client
        for i, b in enumerate(self.drone_ids):
            pb.applyExternalForce(b, -1, force_world[i].tolist(), s.pos_world[i].tolist(), pb.WORLD_FRAME, physicsClientId=c)
            pb.applyExternalTorque(b, -1, torque_world[i].tolist(), pb.WORLD_FRAME, physicsClientId=c)
        pb.stepSimulation(physicsClientId=c)
        self.step_count += 1
        self.time_s = self.step_count * self.dt_s
        self._state = self._read_state()
        self._detect_crashes()
        return self._state

    def _detect_crashes(self) -> None:
        s = self._state
        tilt = np.arccos(np.clip(s.rotation_body_to_world[:, 2, 2], -1.0, 1.0))
        crashed = (s.obstacle_contact & (tilt > self.config.crash_tilt_rad)) & ~self.failed
        for i in np.flatnonzero(crashed):
            self.fail_drone(int(i))
