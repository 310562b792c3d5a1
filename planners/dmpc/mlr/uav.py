"""A UAV of MLR-DMPC: it follows its reference, switches per Eq. 10, answers recovery requests (Sec. 4.2).

One :meth:`Uav.step` per round k, at t = kT, with the payloads received in
round k - 1's communication phase:

* Eq. 10: if a CU message of round k - 1 carried a new trajectory for this
  UAV, the UAV follows it from kT on; otherwise it keeps its trajectory
  (which is the "shift" û(tau + T | k - 1): trajectories are stored in
  absolute time). If two CUs computed it in the same round (only possible in
  the ignore-loss baseline, whose CUs may disagree on A_ET), the one from the
  lower CU index wins (chosen).
* A recovery request of round k - 1 addressed to this UAV is answered in
  round k, in the requesting CU's slot, with the trajectory it follows
  during round k (Alg. 1 Line 25-30).
* Every round it broadcasts a :class:`UavStateMessage`: its measured state,
  its target and the metadata of the trajectory it follows during round k.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
from planners.dmpc.mlr.types import CuTrajectoryMessage, RecoveryReply, RecoveryRequest, UavStateMessage

__all__ = ["INITIAL_ID", "Uav", "initial_trajectory"]

INITIAL_ID = TrajectoryId(-1, -1)  # metadata of every initial trajectory (Remark 2)


def initial_trajectory(config: MlrConfig, pos_world: np.ndarray, t_start_s: float = 0.0) -> ReferenceTrajectory:
    """A UAV's initial trajectory (Remark 2): hover at ``pos_world`` (3,) [m] from ``t_start_s`` [s] on."""
    return ReferenceTrajectory.hover(INITIAL_ID, t_start_s, pos_world, config.n_inputs, config.input_step_s)


class Uav:
    """UAV i.

    Args:
        uav_id: i.
        initial: its initial trajectory (Remark 2).
        target_world: (3,) its initial target [m].
    """

    def __init__(self, uav_id: int, initial: ReferenceTrajectory, target_world: np.ndarray) -> None:
        self.uav_id = int(uav_id)
        self.reference = initial
        self.target_world = np.asarray(target_world, float).reshape(3).copy()
        self.switches: list[tuple[int, ReferenceTrajectory]] = []  # (round, trajectory) of every switch

    def set_target(self, target_world: np.ndarray) -> None:
        """A new mission target (3,) [m]; announced in the next state message."""
        self.target_world = np.asarray(target_world, float).reshape(3).copy()

    def step(
        self, round_index: int, inbox: Sequence[object], pos_world: np.ndarray, vel_world: np.ndarray
    ) -> tuple[list[object], bool]:
        """Round k: switch (Eq. 10), then the payloads to broadcast in round k.

        Args:
            round_index: k.
            inbox: payloads received in round k - 1.
            pos_world: (3,) measured position at kT [m] (for the state message).
            vel_world: (3,) measured velocity at kT [m/s].

        Returns:
            (payloads: the state message, then a reply if one was requested;
            whether the reference switched at kT).
        """
        k = int(round_index)
        mine = sorted(
            (m for m in inbox if isinstance(m, CuTrajectoryMessage) and m.uav_id == self.uav_id),
            key=lambda m: m.cu_id,
        )
        switched = False
        if mine:  # Eq. 10, first case
            self.reference = mine[0].trajectory
            self.switches.append((k, self.reference))
            switched = True
        out: list[object] = [
            UavStateMessage(self.uav_id, k, pos_world, vel_world, self.target_world, self.reference.meta)
        ]
        for req in sorted((m for m in inbox if isinstance(m, RecoveryRequest) and m.uav_id == self.uav_id),
                          key=lambda m: m.cu_id):
            out.append(RecoveryReply(self.uav_id, req.cu_id, k, self.reference))
        return out, switched
