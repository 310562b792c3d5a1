"""What the formation ADMM sends and returns: :class:`CopyMessage`, :class:`MeanMessage`, :class:`AdmmBundle`,
:class:`AdmmStepResult`.

Messages of Algorithm 2 (Stomberg et al.) between neighbours i and j, one pair
per ADMM iteration l (paper Assumption 1: delivered, in order):

* Step 4, :class:`CopyMessage` i -> j: drone i's copy w_ji^{l+1} of j's
  positions (its local QP's solution for them), so that j can average.
* Step 6, :class:`MeanMessage` j -> i: j's average xbar_j^{l+1} of its own
  positions and every neighbour's copy of them (Step 5).

Both carry a (K, 3) trajectory p[1..K] in the world frame (ENU) [m], sampled at
t + k h, k = 1..K, of the MPC step that started at t.

Over a broadcast radio a drone sends one :class:`AdmmBundle` per exchange: the
copies of one iteration for all its neighbours (Step 4), or its mean for all
of them (Step 6); each receiver takes the message addressed to it
(:mod:`mpcde.onboard.admm`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.dmpc.types import DmpcPlan, freeze_array

__all__ = ["AdmmBundle", "AdmmStepResult", "CopyMessage", "MeanMessage", "MeanRecord"]


def _frozen_trajectory(obj: object, name: str) -> None:
    """Field ``name`` of ``obj`` as a read-only (K, 3) float array, K >= 1."""
    freeze_array(obj, name, float, lambda a: a.ndim == 2 and a.shape[1] == 3 and a.shape[0] >= 1, "(K, 3)")


@dataclass(frozen=True)
class _TrajectoryMessage:
    """What both messages of Algorithm 2 carry: a position trajectory from ``sender`` to ``receiver``.

    Attributes:
        sender: id of the sending drone.
        receiver: id of the drone it is addressed to.
        iteration: ADMM iteration l + 1 that produced it (1-based within the MPC step).
        pos_world: (K, 3) positions p[1..K] [m], world frame.
    """

    sender: int
    receiver: int
    iteration: int
    pos_world: np.ndarray

    def __post_init__(self) -> None:
        _frozen_trajectory(self, "pos_world")


@dataclass(frozen=True)
class CopyMessage(_TrajectoryMessage):
    """Algorithm 2 Step 4: the sender's copy of the receiver's position trajectory.

    Attributes:
        sender: id of the drone that holds the copy (i).
        receiver: id of the drone whose trajectory it copies (j, the owner).
        iteration: ADMM iteration l + 1 that produced it (1-based within the MPC step).
        pos_world: (K, 3) w_ji^{l+1}[1..K] [m], world frame.
    """


@dataclass(frozen=True)
class MeanMessage(_TrajectoryMessage):
    """Algorithm 2 Step 6: the sender's averaged own position trajectory.

    Attributes:
        sender: id of the owner (j) that averaged its trajectory.
        receiver: id of a neighbour (i) that holds a copy of it.
        iteration: ADMM iteration l + 1 (1-based within the MPC step).
        pos_world: (K, 3) xbar_j^{l+1}[1..K] [m], world frame.
    """


@dataclass(frozen=True)
class MeanRecord:
    """A mean an owner sent earlier, repeated in its later bundles for holders that missed it.

    Attributes:
        step_index: s, the MPC step of the mean.
        iteration: its ADMM iteration (1-based within the step).
        pos_world: (K, 3) xbar_j [m], world frame.
        averaged: ids of the neighbours whose copies went into it (the others' were lost).
    """

    step_index: int
    iteration: int
    pos_world: np.ndarray
    averaged: tuple[int, ...]

    def __post_init__(self) -> None:
        _frozen_trajectory(self, "pos_world")
        object.__setattr__(self, "averaged", tuple(int(j) for j in self.averaged))


@dataclass(frozen=True)
class AdmmBundle:
    """One drone's broadcast in one exchange of Algorithm 2: its copies (Step 4) or its means (Step 6).

    Exactly one of ``copies`` and ``means`` is non-empty; every message in it
    is from ``sender_id``, of ``iteration``, and addressed to a different
    neighbour. A bundle of means also says whose copies its mean averaged
    and repeats the sender's earlier means (for a lossy radio: a holder whose
    copy was not averaged, or that missed a mean, adjusts its multipliers,
    :mod:`mpcde.onboard.admm`).

    Attributes:
        sender_id: the broadcasting drone i.
        step_index: s, the MPC step the messages belong to (it started at s h).
        iteration: ADMM iteration l + 1 of the messages (1-based within the step).
        copies: one :class:`CopyMessage` w_ji per neighbour j (Step 4).
        means: one :class:`MeanMessage` xbar_i per neighbour j (Step 6; the
            same trajectory for every receiver).
        averaged: with ``means``: the neighbours whose copies xbar_i averages.
        history: with ``means``: the sender's means of earlier iterations
            (the most recent first), which a receiver may have missed.
    """

    sender_id: int
    step_index: int
    iteration: int
    copies: tuple[CopyMessage, ...] = ()
    means: tuple[MeanMessage, ...] = ()
    averaged: tuple[int, ...] = ()
    history: tuple[MeanRecord, ...] = ()

    def __post_init__(self) -> None:
        for name in ("copies", "means", "history"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(self, "averaged", tuple(int(j) for j in self.averaged))
        if bool(self.copies) == bool(self.means):
            raise ValueError(f"AdmmBundle of drone {self.sender_id}: either copies or means, not both or neither")
        if self.copies and (self.averaged or self.history):
            raise ValueError(f"AdmmBundle of drone {self.sender_id}: averaged and history go with means only")
        receivers = [m.receiver for m in self.messages]
        if len(set(receivers)) != len(receivers):
            raise ValueError(f"AdmmBundle of drone {self.sender_id}: two messages for one receiver {receivers}")
        for m in self.messages:
            if m.sender != self.sender_id or m.iteration != self.iteration:
                raise ValueError(
                    f"AdmmBundle of drone {self.sender_id}, iteration {self.iteration}: holds a message of drone "
                    f"{m.sender}, iteration {m.iteration}"
                )

    @property
    def kind(self) -> str:
        """``"copies"`` or ``"means"``."""
        return "copies" if self.copies else "means"

    @property
    def messages(self) -> tuple[CopyMessage, ...] | tuple[MeanMessage, ...]:
        """The copies or the means, whichever the bundle holds."""
        return self.copies or self.means

    def message_for(self, receiver: int) -> CopyMessage | MeanMessage | None:
        """The message addressed to ``receiver``, or None."""
        return next((m for m in self.messages if m.receiver == receiver), None)

    def mean_records(self) -> tuple[MeanRecord, ...]:
        """Every mean the bundle carries as a :class:`MeanRecord`: its own (first), then the history."""
        if not self.means:
            return ()
        own = MeanRecord(self.step_index, self.iteration, self.means[0].pos_world, self.averaged)
        return (own, *self.history)


@dataclass(frozen=True)
class AdmmStepResult:
    """One drone's outcome of one MPC step of ADMM (Algorithm 2 after ``iterations`` iterations).

    The plan is the drone's own part of its last local QP solution z_i^{l}
    (Algorithm 2 returns z_i^l): it satisfies the drone's dynamics and hard
    input limits exactly (up to OSQP's tolerance) even before consensus.

    Attributes:
        drone_id: the drone.
        t0_s: absolute time [s] of the MPC step (the measured state's time).
        h_s: step h [s].
        pos_world: (K+1, 3) p[0..K] [m] (p[0] the measured position).
        vel_world: (K+1, 3) v[0..K] [m/s].
        acc_world: (K, 3) u[0..K-1] [m/s^2], u[k] held on [t0 + k h, t0 + (k+1) h).
        slack: s_i, the soft-constraint slack of paper Remark 2 ([m] / [m/s]).
        iterations: ADMM iterations run.
        primal_residual: (iterations,) ||z_i^{l+1} - zbar_i^{l+1}||_2 per iteration.
        dual_residual: (iterations,) rho ||zbar_i^{l+1} - zbar_i^l||_2 per iteration.
        qp_solve_s: (iterations,) wall time [s] of Step 3 (q update and OSQP solve).
        bookkeeping_s: (iterations,) wall time [s] of this drone's Steps 4-8
            without the network: building messages, averaging, forming zbar,
            the multiplier update.
        osqp_iterations: (iterations,) OSQP iterations of each local QP.
        osqp_rho_updates: total OSQP step-size adaptations (each one a KKT
            refactorisation; 0 with ``osqp_adaptive_rho`` False).
        osqp_max_iter_hits: local QPs that stopped at ``osqp_max_iter`` and
            were used as they were (inexact).
        local_cost: f_i(z_i) of the last local solution (its share of the cost (1a)).
    """

    drone_id: int
    t0_s: float
    h_s: float
    pos_world: np.ndarray
    vel_world: np.ndarray
    acc_world: np.ndarray
    slack: float
    iterations: int
    primal_residual: np.ndarray
    dual_residual: np.ndarray
    qp_solve_s: np.ndarray
    bookkeeping_s: np.ndarray
    osqp_iterations: np.ndarray
    osqp_rho_updates: int
    osqp_max_iter_hits: int
    local_cost: float

    @property
    def input_now(self) -> np.ndarray:
        """(3,) u[0] [m/s^2]: the input to apply on [t0, t0 + h) (with Remark 1 the one fixed at t0)."""
        return self.acc_world[0]

    @property
    def input_next(self) -> np.ndarray:
        """(3,) u[1] [m/s^2]: with Remark 1 the input this step decides for [t0 + h, t0 + 2h)."""
        return self.acc_world[1]

    @property
    def admm_time_s(self) -> float:
        """This drone's compute time for the step [s]: sum of Step 3 and its bookkeeping."""
        return float(np.sum(self.qp_solve_s) + np.sum(self.bookkeeping_s))

    def as_dmpc_plan(self) -> DmpcPlan:
        """The plan as a :class:`DmpcPlan` (acceleration padded with 0 at k = K, its tail convention)."""
        acc = np.vstack([self.acc_world, np.zeros((1, 3))])
        return DmpcPlan(self.t0_s, self.h_s, self.pos_world.copy(), self.vel_world.copy(), acc)
