"""DMPC: per-drone QP over exchanged plans with on-demand or BVC collision avoidance.

Imports :mod:`perception.types` and :mod:`sim.types` only (DESIGN.md section 1).

The names below are imported on first use, so reading a planner's settings
(:mod:`planners.dmpc.config`) does not load the QP solver.
"""

from __future__ import annotations

from planners.lazy_exports import lazy_exports

_WHERE = {
    "BvcPlanes": "planners.dmpc.collision",
    "DmpcConfig": "planners.dmpc.config",
    "DmpcPlan": "planners.dmpc.types",
    "DmpcProblem": "planners.dmpc.qp",
    "DmpcResult": "planners.dmpc.qp",
    "DmpcSolveError": "planners.dmpc.qp",
    "ObstacleConflicts": "planners.dmpc.obstacle",
    "ObstacleRows": "planners.dmpc.obstacle",
    "OnDemandConstraints": "planners.dmpc.collision",
    "PredictionMatrices": "planners.dmpc.model",
    "QpSnapshot": "planners.dmpc.qp",
    "bvc_planes": "planners.dmpc.collision",
    "discrete_model": "planners.dmpc.model",
    "ellipsoidal_distance": "planners.dmpc.collision",
    "fine_position_matrices": "planners.dmpc.model",
    "first_conflict_step": "planners.dmpc.collision",
    "hermite_positions": "planners.dmpc.sampling",
    "implied_half_spaces": "planners.dmpc.reach",
    "obstacle_conflicts": "planners.dmpc.obstacle",
    "obstacle_rows": "planners.dmpc.obstacle",
    "on_demand_constraints": "planners.dmpc.collision",
    "prediction_matrices": "planners.dmpc.model",
    "reach_boxes": "planners.dmpc.reach",
    "rollout": "planners.dmpc.model",
    "sample_predictions": "planners.dmpc.sampling",
    "stack_obstacles": "planners.dmpc.obstacle",
}

__all__ = sorted(_WHERE)
__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
