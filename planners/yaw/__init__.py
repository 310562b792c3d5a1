"""Active yaw planner of MP-CDE (Sec. IV-A, Alg. 1): safety margin, exploring, observing, tracking.

Imports :mod:`perception.types` only (DESIGN.md section 1). Typical use, every t_y::

    planner = YawPlanner(YawPlannerConfig())
    plan = planner.plan(t, yaw, TrajectoryView(traj.pos, traj.vel, traj_end_s), snapshot, predictions)
    yaw_ref, yaw_rate_ref = plan.yaw_at(t_control)
    if needs_replan(plan.safety_margin_s, plan.tau_thr_s, plan.min_neighbour_distance_m, 0.7):
        ...  # MINCO replan (Alg. 1 line 13)
"""

from planners.yaw.config import YawPlannerConfig
from planners.yaw.coverage import (
    FanCast,
    FanGeometry,
    cast_fans,
    edge_gains,
    past_coverage,
    ray_gains,
    visible_cells_xy,
)
from planners.yaw.lattice import LatticePath, edge_costs, shortest_path
from planners.yaw.planner import YawPlanner
from planners.yaw.safety import needs_replan, safe_regime, safety_margin
from planners.yaw.steering import mean_bearing, observe_targets, rate_limited, sweep_offsets, track_targets
from planners.yaw.types import MODES, SafetyMargin, TrajectoryView, YawPlan
from planners.yaw.visibility import layer_weights, visibility_rewards, wrap_angle

__all__ = [
    "MODES",
    "FanCast",
    "FanGeometry",
    "LatticePath",
    "SafetyMargin",
    "TrajectoryView",
    "YawPlan",
    "YawPlanner",
    "YawPlannerConfig",
    "cast_fans",
    "edge_costs",
    "edge_gains",
    "layer_weights",
    "mean_bearing",
    "needs_replan",
    "observe_targets",
    "past_coverage",
    "ray_gains",
    "rate_limited",
    "safe_regime",
    "safety_margin",
    "shortest_path",
    "sweep_offsets",
    "track_targets",
    "visibility_rewards",
    "visible_cells_xy",
    "wrap_angle",
]
