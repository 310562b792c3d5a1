"""Active yaw planner of MP-CDE (Sec. IV-A, Alg. 1): safety margin, exploring, observing, tracking.

Imports :mod:`perception.types` only (DESIGN.md section 1). Typical use, every t_y::

    planner = YawPlanner(YawPlannerConfig())
    plan = planner.plan(t, yaw, TrajectoryView(traj.pos, traj.vel, traj_end_s), snapshot, predictions)
    yaw_ref, yaw_rate_ref = plan.yaw_at(t_control)
    if needs_replan(plan.safety_margin_s, plan.tau_thr_s, plan.min_neighbour_distance_m, 0.7):
        ...  # MINCO replan (Alg. 1 line 13)

The names below are imported on first use, so reading one module's settings
does not load the rest of the package.
"""

from __future__ import annotations

from planners.lazy_exports import lazy_exports

_WHERE = {
    "FanCast": "planners.yaw.coverage",
    "FanGeometry": "planners.yaw.coverage",
    "LatticePath": "planners.yaw.lattice",
    "MODES": "planners.yaw.types",
    "SafetyMargin": "planners.yaw.types",
    "TrajectoryView": "planners.yaw.types",
    "YawPlan": "planners.yaw.types",
    "YawPlanner": "planners.yaw.planner",
    "YawPlannerConfig": "planners.yaw.config",
    "ZhouYawPlanner": "planners.yaw.zhou",
    "explore_yaws": "planners.yaw.explore",
    "make_yaw_planner": "planners.yaw.planner",
    "cast_fans": "planners.yaw.coverage",
    "edge_costs": "planners.yaw.lattice",
    "edge_gains": "planners.yaw.coverage",
    "layer_weights": "planners.yaw.visibility",
    "mean_bearing": "planners.yaw.steering",
    "needs_replan": "planners.yaw.safety",
    "observe_targets": "planners.yaw.steering",
    "past_coverage": "planners.yaw.coverage",
    "rate_limited": "planners.yaw.steering",
    "ray_gains": "planners.yaw.coverage",
    "safe_regime": "planners.yaw.safety",
    "safety_margin": "planners.yaw.safety",
    "shortest_path": "planners.yaw.lattice",
    "sweep_offsets": "planners.yaw.steering",
    "track_targets": "planners.yaw.steering",
    "visibility_rewards": "planners.yaw.visibility",
    "visible_cells_xy": "planners.yaw.coverage",
    "wrap_angle": "planners.yaw.visibility",
}

__all__ = sorted(_WHERE)
__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
