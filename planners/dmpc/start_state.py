"""Where a communicating drone's next plan starts: its own plan's state, or its pose estimate.

The rule DMPC (``dmpc.state_tolerance_*``, :mod:`mpcde.onboard.dmpc`) and ADMM
(``admm.state_tolerance_*``, :mod:`mpcde.onboard.admm`) share. At a planning
time t the drone holds its pose estimate (p_hat, v_hat), extrapolated to t,
and its previous plan's state (p_plan(t), v_plan(t)). The next plan starts at

    x0 = (p_plan, v_plan)   if ||p_plan - p_hat|| <= tol_m and ||v_plan - v_hat|| <= tol_mps,
    x0 = (p_hat, v_hat)     otherwise (a *reset*).

Why not always the estimate: the plans' goal and formation costs act over the
horizon, so each plan moves slowly in its first steps; restarting every plan
from the estimate feeds the estimate's noise and the controller's lag into
every first step, and the drones drift off their goals
(docs/results/dmpc_agent.md#the-8-drone-swap-replanning-from-the-estimate-against-from-the-plan). Why not always the plan: a drone pushed off its
plan (a gust, a contact, a failed solve) must plan from where it is.

Why the tolerance sits above the estimate's drift (:data:`TOLERANCE_M`,
0.3 m): the SE(3) controller tracks the plan with the *true* state, so the
estimate differs from a well-tracked plan by the estimate's error. Its drift
is a random walk of ``pos_drift_m_per_sqrt_s`` = 5 mm/sqrt(s) per axis
(:mod:`sim.pose_estimate`); by 100 s its norm (chi, 3 degrees of freedom,
sigma 0.05 m) passes 0.1 m with probability 0.26 per drone and 0.3 m with
under 1e-6. Past the tolerance every plan restarts from the estimate, the
controller moves the drone by the drift to follow it, the estimate moves with
the drone, and the next plan restarts lower again: a ratchet that holds DMPC
drones short of their goals and then sinks them
(docs/results/dmpc_agent.md#the-tolerance-against-the-pose-estimates-drift-dmpcstate_tolerance_m-01---03-m).
Limit: flights much longer than 100 s drift further (past 0.3 m with
probability 0.007 per drone by 300 s). 0 for both tolerances always starts
from the estimate.
"""

from __future__ import annotations

import numpy as np

TOLERANCE_M = 0.3
"""Default position tolerance [m] of both agents (module docstring: above the drift)."""

TOLERANCE_MPS = 0.3
"""Default velocity tolerance [m/s] of both agents."""


def plan_start_state(
    est_pos: np.ndarray, est_vel: np.ndarray, plan_pos: np.ndarray, plan_vel: np.ndarray, tol_m: float, tol_mps: float
) -> tuple[np.ndarray, np.ndarray, bool]:
    """x0 of the next plan: ``(pos (3,) m, vel (3,) m/s, from_plan)``; ``from_plan`` False is a reset.

    ``est_*`` is the pose estimate extrapolated to the planning time, ``plan_*``
    the previous plan's (or the start hover's) state at that time.
    """
    est_pos, est_vel = np.asarray(est_pos, float), np.asarray(est_vel, float)
    plan_pos, plan_vel = np.asarray(plan_pos, float), np.asarray(plan_vel, float)
    if np.linalg.norm(plan_pos - est_pos) <= tol_m and np.linalg.norm(plan_vel - est_vel) <= tol_mps:
        return plan_pos, plan_vel, True
    return est_pos, est_vel, False
