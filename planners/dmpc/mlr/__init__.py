"""Message-loss-recovery DMPC (MLR-DMPC, DMPC-Swarm Sec. 4): trackers, event trigger, QP, CU and UAV.

Imports numpy, scipy, osqp and planners.* only (DESIGN.md section 1); the
round-based swarm driver that connects them over ``sim.radio`` is
:mod:`mpcde.mlr_swarm`; the onboard agent that flies them in the physics
loop, with the first M drones hosting the CUs, is :mod:`mpcde.agent_mlr`.
"""

from planners.dmpc.mlr.config import TRIGGERS, MlrConfig
from planners.dmpc.mlr.qp import BvcRows, MlrProblem, MlrQpResult, time_varying_bvc
from planners.dmpc.mlr.tracker import InformationTrackers, TrackerEntry, TrackerUpdate
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
from planners.dmpc.mlr.trigger import consensus, event_set, quantize, raw_priorities, selected_uav
from planners.dmpc.mlr.types import CuTrajectoryMessage, MlrBundle, RecoveryReply, RecoveryRequest, UavStateMessage

__all__ = [
    "TRIGGERS",
    "BvcRows",
    "CuTrajectoryMessage",
    "InformationTrackers",
    "MlrBundle",
    "MlrConfig",
    "MlrProblem",
    "MlrQpResult",
    "RecoveryReply",
    "RecoveryRequest",
    "ReferenceTrajectory",
    "TrackerEntry",
    "TrackerUpdate",
    "TrajectoryId",
    "UavStateMessage",
    "consensus",
    "event_set",
    "quantize",
    "raw_priorities",
    "selected_uav",
]
