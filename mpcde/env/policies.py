"""The package's own stacks as policies over the environments' observations.

:class:`StackPolicy` runs one onboard agent of a stack (``denied``,
``comm``, ``auto``, ``placeholder``; :func:`mpcde.stacks.build.make_agent`)
per learner and feeds it from the observation only:

* ``pose`` -> ``on_pose_estimate`` whenever the estimate's time changes;
* ``camera`` (+ ``detections``) -> ``on_frame`` whenever the capture time
  changes (invalid depth, 0 in the observation, back to NaN);
* ``radio`` -> ``on_radio`` with the newer plans of its slots, then
  ``plan_round``, at the radio rounds of the drone's own clock
  (k / ``radio.rate_hz``, as the session runs them);

and returns the agent's reference as a ``"reference"`` action (position,
velocity, acceleration, yaw, yaw rate). What it may know besides is what a
drone is told before take-off: the scenario (its goals, the mapped obstacles
the DMPC stacks are given, the settings).

Exactness: with ``control_hz`` equal to ``physics.physics_hz`` (the action is
read at every physics tick, as the session reads a stack's reference),
``broadcast=False`` and ``detections`` observed (so that the env's own
tracker, which the metrics score, sees what the stack's does), the ``denied``
policy flies the very flight of
``mpcde fly --mode denied`` on the same seed: the same states and metrics
(tests/integration/test_env_policy.py). Radio-using stacks run too, with two
differences from ``mpcde fly``: their neighbours hear the plan the env builds
from the held action (:class:`mpcde.env.external.ExternalDrone`) rather than the
stack's own, and the plans they hear come resampled through the observation's
fixed slots.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from mpcde.stacks import get_stack, stacks
from mpcde.errors import ConfigError
from perception.types import Detection
from sim.types import PlanMessage, PoseEstimate, RadioMessage, RgbdFrame

__all__ = ["EXACT_REPLAY_OPTIONS", "StackPolicy"]

EPS_S = 1e-9  # the session's tolerance on its rates' ticks (mpcde.flight.session.EPS_S; not importable here: onboard rule)

EXACT_REPLAY_OPTIONS: dict[str, Any] = {
    "control_hz": 240.0, "action": "reference", "observe": ("pose", "goal", "camera", "detections"), "broadcast": False,
    "copy_images": False, "terminate_on_collision": False, "terminate_on_arrival": False,
    "max_speed_mps": 20.0, "max_accel_mps2": 50.0, "max_yaw_rate_rps": 20.0,
}  # fmt: skip
"""EnvOptions under which the ``denied`` policy flies exactly ``mpcde fly``'s flight (module docstring):
the physics rate, a silent radio, detections for the env's scored tracker, no early terminations, and bounds
wide enough for any reference the stack flies (one read-only image copy per frame: 240 Hz steps)."""


def solo_modes() -> tuple[str, ...]:
    """The registered stacks whose drones each plan alone (not ``uses.joint``: MLR-DMPC's compute units and ADMM's
    sub-rounds need every drone), so that they can fly some of an environment's drones: a policy's learners, or
    the neighbours of :class:`mpcde.env.SingleDroneEnv`."""
    return tuple(s.name for s in stacks() if not s.uses.joint)


class StackPolicy:
    """A stack flying an environment's learners from their observations.

    Args:
        mode: the stack (a registered name, :func:`mpcde.stacks.stacks`; not
            one whose drones compute together, ``uses.joint``: ``mlr``, ``admm``).
        env: a :class:`mpcde.env.SwarmParallelEnv` or
            :class:`mpcde.env.SingleDroneEnv` with ``action="reference"``;
            the policy reads the scenario from it, and rebuilds its agents at
            every new episode (an observation at time 0).

    Call it with the parallel env's observation dict (agent -> observation)
    to get the action dict, or use :meth:`act` for one agent.
    """

    def __init__(self, mode: str, env: Any) -> None:
        alone = solo_modes()
        if mode not in alone:
            raise ConfigError("policy.mode", mode, f"one of {', '.join(alone)}")
        core = getattr(env, "unwrapped", env).core
        if core.options.action != "reference":
            raise ConfigError("env.action", core.options.action, "reference (a stack policy outputs a flat-output reference)")
        self.mode = mode
        self.core = core
        self.agents: dict[str, Any] = {}
        self.seen: dict[str, dict] = {}

    def _start(self) -> None:
        """Fresh agents for the episode the env has just started."""
        from mpcde.onboard.budget import ComputeBudget
        from mpcde.stacks.build import make_agent

        p = self.core.prepared
        cfg = replace(p.config, planner=replace(p.config.planner, kind=get_stack(self.mode).kind))
        budget = ComputeBudget()
        self.agents = {a: make_agent(cfg, i, p.goals, p.obstacles, budget) for a, i in self.core.index.items()}
        self.seen = {a: {"pose": None, "frame": None, "next_radio": 0.0, "plans": {}} for a in self.agents}
        self.radio_period = 1.0 / cfg.radio.rate_hz
        self.episode = self.core.session

    def __call__(self, observations: dict[str, dict]) -> dict[str, np.ndarray]:
        """Actions of every agent in ``observations``."""
        return {a: self.act(a, o) for a, o in observations.items()}

    def act(self, agent: str, obs: dict) -> np.ndarray:
        """The reference action (11,) of ``agent`` for its observation ``obs``."""
        if not self.agents or self.core.session is not self.episode:
            self._start()
        a, seen = self.agents[agent], self.seen[agent]
        t = float(obs["time_s"][0])
        pose = obs.get("pose")
        if pose is not None and seen["pose"] != float(pose["time_s"][0]):
            seen["pose"] = float(pose["time_s"][0])
            a.on_pose_estimate(PoseEstimate(time_s=seen["pose"], pos_world=pose["pos_world"].copy(), vel_world=pose["vel_world"].copy(), quat_xyzw=pose["quat_xyzw"].copy(), ang_vel_body=pose["ang_vel_body"].copy()))
        cam = obs.get("camera")
        if cam is not None and cam["time_s"][0] >= 0 and seen["frame"] != float(cam["time_s"][0]):
            seen["frame"] = float(cam["time_s"][0])
            depth = np.where(cam["depth_m"] > 0, cam["depth_m"], np.float32(np.nan)).astype(np.float32)
            frame = RgbdFrame(drone_id=a.drone_id, time_s=seen["frame"], rgb=cam["rgb"], depth_m=depth, K=cam["K"], transform_camera_to_world=cam["transform_camera_to_world"])
            a.on_frame(frame, _detections(obs) if a.detector_request is not None else None)
        if t >= seen["next_radio"] - EPS_S:
            a.on_radio(_new_plans(obs.get("radio"), t, seen["plans"]))
            a.plan_round(t)
            a.outgoing(t)  # the env broadcasts the held action's plan (module docstring)
            seen["next_radio"] += self.radio_period
        r = a.reference(t)
        return np.r_[r.pos_world, r.vel_world, r.acc_world, r.yaw, r.yaw_rate].astype(np.float64)


def _detections(obs: dict) -> list[Detection] | None:
    """The frame's boxes from the ``detections`` entry (None without it: the agent then tracks nothing)."""
    d = obs.get("detections")
    if d is None:
        return None
    return [Detection(box_xyxy=d["boxes_xyxy"][j].copy(), score=float(d["scores"][j])) for j in np.flatnonzero(d["valid"])]


def _new_plans(radio: dict | None, t: float, last_sent: dict[int, float]) -> list[RadioMessage]:
    """Radio messages rebuilt from the ``radio`` slots whose plans are newer than the last ones handed on."""
    if radio is None:
        return []
    out = []
    for j in np.flatnonzero(radio["valid"]):
        sender = int(radio["sender"][j])
        sent = t - float(radio["age_s"][j])
        if last_sent.get(sender, -np.inf) >= sent - EPS_S:
            continue
        last_sent[sender] = sent
        plan = PlanMessage(sender_id=sender, time_s=sent, times_s=t + radio["times_s"][j], pos_world=radio["pos_world"][j].copy(), vel_world=radio["vel_world"][j].copy())
        out.append(RadioMessage(sender_id=sender, send_time_s=sent, receive_time_s=t, payload=plan))
    return out
