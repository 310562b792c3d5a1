"""Message-loss-recovery DMPC (MLR-DMPC, DMPC-Swarm Sec. 4): trackers, event trigger, QP, CU and UAV.

Imports numpy, scipy, osqp and planners.* only (DESIGN.md section 1); the
round-based swarm driver that connects them over ``sim.radio`` is
:mod:`mpcde.evals.mlr_swarm`; the onboard agent that flies them in the physics
loop, with the first M drones hosting the CUs, is :mod:`mpcde.onboard.mlr`.

The names below are imported on first use, so reading one module's settings
does not load the rest of the package.
"""

from __future__ import annotations

from planners.lazy_exports import lazy_exports

_WHERE = {
    "BvcRows": "planners.dmpc.mlr.qp",
    "CuTrajectoryMessage": "planners.dmpc.mlr.types",
    "InformationTrackers": "planners.dmpc.mlr.tracker",
    "MlrBundle": "planners.dmpc.mlr.types",
    "MlrConfig": "planners.dmpc.mlr.config",
    "MlrProblem": "planners.dmpc.mlr.qp",
    "MlrQpResult": "planners.dmpc.mlr.qp",
    "RecoveryReply": "planners.dmpc.mlr.types",
    "RecoveryRequest": "planners.dmpc.mlr.types",
    "ReferenceTrajectory": "planners.dmpc.mlr.trajectory",
    "TRIGGERS": "planners.dmpc.mlr.config",
    "TrackerEntry": "planners.dmpc.mlr.tracker",
    "TrackerUpdate": "planners.dmpc.mlr.tracker",
    "TrajectoryId": "planners.dmpc.mlr.trajectory",
    "UavStateMessage": "planners.dmpc.mlr.types",
    "consensus": "planners.dmpc.mlr.trigger",
    "event_set": "planners.dmpc.mlr.trigger",
    "quantize": "planners.dmpc.mlr.trigger",
    "raw_priorities": "planners.dmpc.mlr.trigger",
    "selected_uav": "planners.dmpc.mlr.trigger",
    "time_varying_bvc": "planners.dmpc.mlr.qp",
}

__all__ = sorted(_WHERE)
__getattr__, __dir__ = lazy_exports(__name__, _WHERE)
