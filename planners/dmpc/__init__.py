"""DMPC: per-drone QP over exchanged plans with on-demand or BVC collision avoidance.

Imports :mod:`perception.types` and :mod:`sim.types` only (DESIGN.md section 1).
"""

from planners.dmpc.collision import (
    BvcPlanes,
    OnDemandConstraints,
    bvc_planes,
    ellipsoidal_distance,
    first_conflict_step,
    on_demand_constraints,
)
from planners.dmpc.config import DmpcConfig
from planners.dmpc.model import (
    PredictionMatrices,
    discrete_model,
    fine_position_matrices,
    prediction_matrices,
    rollout,
)
from planners.dmpc.obstacle import ObstacleConflicts, ObstacleRows, obstacle_conflicts, obstacle_rows, stack_obstacles
from planners.dmpc.qp import DmpcProblem, DmpcResult, DmpcSolveError, QpSnapshot
from planners.dmpc.reach import implied_half_spaces, reach_boxes
from planners.dmpc.sampling import hermite_positions, sample_predictions
from planners.dmpc.types import DmpcPlan

__all__ = [
    "BvcPlanes",
    "DmpcConfig",
    "DmpcPlan",
    "DmpcProblem",
    "DmpcResult",
    "DmpcSolveError",
    "ObstacleConflicts",
    "ObstacleRows",
    "OnDemandConstraints",
    "PredictionMatrices",
    "QpSnapshot",
    "bvc_planes",
    "discrete_model",
    "ellipsoidal_distance",
    "fine_position_matrices",
    "first_conflict_step",
    "hermite_positions",
    "implied_half_spaces",
    "obstacle_conflicts",
    "obstacle_rows",
    "on_demand_constraints",
    "prediction_matrices",
    "reach_boxes",
    "rollout",
    "sample_predictions",
    "stack_obstacles",
]
