"""The messages of MLR-DMPC (DMPC-Swarm Sec. 4.2, Alg. 1 and 2): what UAVs and CUs broadcast each round.

Every round k has a computation phase then a communication phase (Sec. 3.1,
Fig. 1). In the communication phase every UAV sends a :class:`UavStateMessage`
in its own slot, and every CU w sends in its slot either a
:class:`CuTrajectoryMessage` (a new trajectory, or none, plus its priorities)
or a :class:`RecoveryRequest` (MLR, Alg. 1 Line 25). One round after a
request, the CU stays silent and the requested UAV sends a
:class:`RecoveryReply` in the CU's slot (Alg. 1 Line 30). Messages of round k
are read in round k + 1's computation phase. Positions are world frame, z up, [m].

:class:`MlrBundle` is what one drone broadcasts per round when the UAVs
themselves host the CUs (:mod:`mpcde.onboard.mlr`): a radio with one payload
per drone and round carries the UAV's messages and its CU's message together.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
from planners.dmpc.types import freeze_array

__all__ = ["CuTrajectoryMessage", "MlrBundle", "RecoveryReply", "RecoveryRequest", "UavStateMessage"]


def _frozen_vector(obj: object, name: str, size: int | None = None, dtype: type = float) -> None:
    """Field ``name`` of ``obj`` as a read-only 1-D ``dtype`` array (of ``size`` entries unless None)."""
    freeze_array(obj, name, dtype, lambda a: a.ndim == 1 and (size is None or a.size == size), f"({size or 'N'},)")


@dataclass(frozen=True)
class UavStateMessage:
    """A UAV's broadcast in its own slot of round k (Sec. 4.2.1).

    Attributes:
        uav_id: i in 0..N-1.
        round_index: k.
        pos_world: (3,) the UAV's measured position at the start of round k [m].
        vel_world: (3,) measured velocity [m/s].
        target_world: (3,) its current target p_i,target [m].
        following: metadata of the reference trajectory it follows during round k.
    """

    uav_id: int
    round_index: int
    pos_world: np.ndarray
    vel_world: np.ndarray
    target_world: np.ndarray
    following: TrajectoryId

    def __post_init__(self) -> None:
        for name in ("pos_world", "vel_world", "target_world"):
            _frozen_vector(self, name, 3)


@dataclass(frozen=True)
class CuTrajectoryMessage:
    """A CU's broadcast of round k: the MLR-DMPC result and its priorities (Alg. 1 Line 35).

    Attributes:
        cu_id: w in 0..M-1.
        round_index: k.
        priorities: (N,) uint8 J_{i,w}(k) for the next round's consensus
            (Appendix A; 0 for the UAV the CU just recomputed).
        uav_id: the UAV it computed, or None (nothing computed this round).
        trajectory: the new trajectory for ``uav_id`` (meta (k, w), starts
            at (k + 1) T), or None.
        repeat_uav_id, repeat_trajectory: with ``MlrConfig.repeat_trajectory``,
            the trajectory this CU computed in round k - 1 (meta (k - 1, w)),
            sent again so that a CU that lost that message gets it one round
            late (:mod:`planners.dmpc.mlr.tracker`, step 0); None otherwise.
            Not in DMPC-Swarm: it doubles the message's trajectory payload.
    """

    cu_id: int
    round_index: int
    priorities: np.ndarray
    uav_id: int | None = None
    trajectory: ReferenceTrajectory | None = None
    repeat_uav_id: int | None = None
    repeat_trajectory: ReferenceTrajectory | None = None

    def __post_init__(self) -> None:
        _frozen_vector(self, "priorities", dtype=np.uint8)
        if (self.uav_id is None) != (self.trajectory is None):
            raise ValueError(f"uav_id={self.uav_id!r}: given exactly when a trajectory is given")
        if (self.repeat_uav_id is None) != (self.repeat_trajectory is None):
            raise ValueError(f"repeat_uav_id={self.repeat_uav_id!r}: given exactly when a repeat_trajectory is given")


@dataclass(frozen=True)
class RecoveryRequest:
    """A CU in MLR asks a UAV for the trajectory it follows (Alg. 1 Line 25).

    The CU donates its slot of round k + 1 to the UAV (Line 30).

    Attributes:
        cu_id: w.
        round_index: k.
        priorities: (N,) uint8 J_{i,w}(k) (the CU still takes part in the consensus).
        uav_id: the UAV whose trajectory is requested.
    """

    cu_id: int
    round_index: int
    priorities: np.ndarray
    uav_id: int

    def __post_init__(self) -> None:
        _frozen_vector(self, "priorities", dtype=np.uint8)


@dataclass(frozen=True)
class RecoveryReply:
    """A UAV's answer to a request, sent in the requesting CU's slot of the next round.

    Attributes:
        uav_id: i.
        slot_cu_id: w, the CU that requested it and donated its slot.
        round_index: k, the round in which the reply is sent.
        trajectory: the reference trajectory i follows during round k (with its metadata).
    """

    uav_id: int
    slot_cu_id: int
    round_index: int
    trajectory: ReferenceTrajectory


@dataclass(frozen=True)
class MlrBundle:
    """Everything one drone broadcasts in round k: its UAV's messages and, if it hosts a CU, that CU's.

    The paper gives every UAV and every CU a slot of its own (Sec. 3.1, Fig. 1)
    and sends a recovery reply in the requesting CU's donated slot; here the
    drone's payloads share one radio message, so they are lost together. The
    receiving CU still accounts for a donated slot by the reply's
    ``slot_cu_id``, wherever the reply travelled.

    Attributes:
        state: the UAV's state message of round k (it names the sender and the round).
        replies: the UAV's recovery replies of round k (one per request it received in round k - 1).
        cu_message: the hosted CU's message of round k, or None (no CU on
            this drone, it has not started, or it donates its slot).
        initial: the UAV's initial trajectory while it still follows it, else
            None: the CUs learn the initial trajectories (Remark 2) from it.
    """

    state: UavStateMessage
    replies: tuple[RecoveryReply, ...] = ()
    cu_message: CuTrajectoryMessage | RecoveryRequest | None = None
    initial: ReferenceTrajectory | None = None

    def __post_init__(self) -> None:
        k, i = self.state.round_index, self.state.uav_id
        object.__setattr__(self, "replies", tuple(self.replies))
        for r in self.replies:
            if r.uav_id != i or r.round_index != k:
                raise ValueError(f"replies: uav {r.uav_id} round {r.round_index}, expected uav {i} round {k}")
        if self.cu_message is not None and self.cu_message.round_index != k:
            raise ValueError(f"cu_message.round_index={self.cu_message.round_index!r}: the bundle's round {k}")
        if self.initial is not None and self.initial.meta.calc_round >= 0:
            raise ValueError(f"initial.meta={self.initial.meta!r}: an initial trajectory (calc_round -1)")

    @property
    def sender_id(self) -> int:
        """The drone (UAV i) that sent the bundle."""
        return self.state.uav_id

    @property
    def round_index(self) -> int:
        """k."""
        return self.state.round_index

    def messages(self) -> list[object]:
        """The MLR messages it carries: the state message, the replies, then the CU message if any."""
        out: list[object] = [self.state, *self.replies]
        if self.cu_message is not None:
            out.append(self.cu_message)
        return out
