"""The environments' action spaces and how an action becomes the controller's reference.

Two modes (:attr:`mpcde.env.options.EnvOptions.action`); in both the action
taken at a control step at time t0 is held until the next one, and the
SE(3) controller (:class:`sim.vehicle.controller.SE3Controller`) tracks, at
every physics tick t in [t0, t0 + 1/control_hz), tau = t - t0:

* ``"velocity"``, a = (v_x, v_y, v_z, r) [m/s, rad/s]: the reference starts at
  the drone's own pose estimate at t0 (position p0, heading psi0) and moves
  with the command: p(t) = p0 + v tau, v(t) = v, a(t) = 0, psi(t) = psi0 + r tau,
  psi_dot = r. The position error is zero at each step start, so this is a
  velocity loop (as gym-pybullet-drones' VEL action); onboard only: the
  anchor is the estimate, never the truth.
* ``"reference"``, a = (p, v, a, psi, psi_dot) (11,): a flat-output reference
  at t0 held with constant acceleration: p(t) = p + v tau + a tau^2 / 2,
  v(t) = v + a tau, a(t) = a, psi(t) = psi + psi_dot tau. At control_hz =
  physics_hz (tau = 0 at every tick) the controller gets the action itself, which
  is how :class:`mpcde.env.policies.StackPolicy` flies a stack exactly.

Bounds: speeds within ``max_speed_mps`` per axis, accelerations within
``max_accel_mps2``, yaw rates within ``max_yaw_rate_rps``, positions within the
scenario's flying box (its ``arena_size_m`` around the origin, z in
[0, ``world.ceiling_m``]... see :func:`action_space`), yaw any angle in
[-YAW_BOUND_RAD, YAW_BOUND_RAD] (the controller wraps it).
"""

from __future__ import annotations

import numpy as np

from sim.types import FlatOutputReference

__all__ = ["YAW_BOUND_RAD", "ActionHold", "action_bounds", "check_action"]

YAW_BOUND_RAD = 1000.0
"""Yaw bound of the reference action [rad]: any heading, unwrapped as a stack plans it."""


def action_bounds(mode: str, max_speed: float, max_accel: float, max_yaw_rate: float, box_low: np.ndarray, box_high: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple[str, ...]]:
    """The action box of ``mode``: low (k,), high (k,) and each element's name.

    Args:
        mode: ``"velocity"`` or ``"reference"``.
        max_speed, max_accel, max_yaw_rate: per-axis bounds [m/s, m/s^2, rad/s].
        box_low, box_high: (3,) the flying box [m] (reference positions).
    """
    v = np.full(3, max_speed)
    if mode == "velocity":
        return np.r_[-v, -max_yaw_rate], np.r_[v, max_yaw_rate], ("vx", "vy", "vz", "yaw_rate")
    a = np.full(3, max_accel)
    low = np.r_[box_low, -v, -a, -YAW_BOUND_RAD, -max_yaw_rate]
    high = np.r_[box_high, v, a, YAW_BOUND_RAD, max_yaw_rate]
    return low, high, ("x", "y", "z", "vx", "vy", "vz", "ax", "ay", "az", "yaw", "yaw_rate")


def check_action(agent: str, action: object, low: np.ndarray, high: np.ndarray, names: tuple[str, ...], clip: bool) -> tuple[np.ndarray | None, bool]:
    """An agent's action as a float64 (k,) array inside the box.

    Args:
        agent: the agent's name (for the error).
        action: what the learner passed.
        low, high, names: from :func:`action_bounds`.
        clip: clip into the box instead of raising; a NaN action becomes None (hover).

    Returns:
        (the action or None, whether it was changed).

    Raises:
        ValueError: one line naming ``actions[<agent>][<element>]``, the value
            and the bounds (a wrong shape or a non-number always raises).
    """
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError(f"actions[{agent!r}]: a ({low.size},) array of numbers expected, got {type(action).__name__}") from None
    if a.shape != low.shape:
        raise ValueError(f"actions[{agent!r}]: shape {a.shape}, expected ({low.size},) = ({', '.join(names)})")
    bad = ~((a >= low) & (a <= high))  # NaN is bad too
    if not bad.any():
        return a, False
    if not clip:
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"actions[{agent!r}][{k}] ({names[k]})={float(a[k])!r}: a number in [{low[k]:g}, {high[k]:g}]")
    if np.isnan(a).any():
        return None, True
    return np.clip(a, low, high), True


class ActionHold:
    """One drone's action held between control steps as a reference at any tick (module docstring's equations).

    Args:
        mode: ``"velocity"`` or ``"reference"``.
    """

    def __init__(self, mode: str) -> None:
        self.mode = mode
        self.t0 = 0.0
        self.action: np.ndarray | None = None
        self.anchor_pos = np.zeros(3)
        self.anchor_yaw = 0.0

    def hover(self, t0: float, pos: np.ndarray, yaw: float) -> None:
        """Hold position ``pos`` [m] and heading ``yaw`` [rad] from ``t0`` [s] (no action, or a terminated drone)."""
        self.t0, self.action, self.anchor_pos, self.anchor_yaw = t0, None, np.array(pos, float), float(yaw)

    def set(self, t0: float, action: np.ndarray, est_pos: np.ndarray, est_yaw: float) -> None:
        """Hold ``action`` from ``t0`` [s]; ``est_pos`` [m] and ``est_yaw`` [rad] anchor a velocity action."""
        self.t0, self.action = t0, action
        self.anchor_pos, self.anchor_yaw = np.array(est_pos, float), float(est_yaw)

    def reference(self, t: float) -> FlatOutputReference:
        """The reference at tick ``t`` [s]."""
        tau = t - self.t0
        a = self.action
        if a is None:
            return FlatOutputReference.hover(self.anchor_pos, self.anchor_yaw)
        if self.mode == "velocity":
            v = a[:3]
            return FlatOutputReference(pos_world=self.anchor_pos + v * tau, vel_world=v.copy(), acc_world=np.zeros(3), yaw=self.anchor_yaw + a[3] * tau, yaw_rate=float(a[3]))
        if tau == 0.0:
            return FlatOutputReference(pos_world=a[0:3].copy(), vel_world=a[3:6].copy(), acc_world=a[6:9].copy(), yaw=float(a[9]), yaw_rate=float(a[10]))
        p, v, acc = a[0:3], a[3:6], a[6:9]
        return FlatOutputReference(pos_world=p + v * tau + 0.5 * acc * tau * tau, vel_world=v + acc * tau, acc_world=acc.copy(), yaw=float(a[9] + a[10] * tau), yaw_rate=float(a[10]))

    def pos_vel_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities (K, 3) of the held action at times ``t`` (K,) [s] (the plan a drone broadcasts)."""
        tau = (np.asarray(t, float) - self.t0)[:, None]
        a = self.action
        if a is None:
            return np.repeat(self.anchor_pos[None], tau.shape[0], 0), np.zeros((tau.shape[0], 3))
        if self.mode == "velocity":
            return self.anchor_pos + a[:3] * tau, np.repeat(a[None, :3], tau.shape[0], 0)
        return a[0:3] + a[3:6] * tau + 0.5 * a[6:9] * tau**2, a[3:6] + a[6:9] * tau
