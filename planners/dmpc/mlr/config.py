"""Configuration of message-loss-recovery DMPC (MLR-DMPC, DMPC-Swarm Sec. 4): :class:`MlrConfig`.

The paper is Gräfe et al., "DMPC-Swarm: distributed model predictive control
on nano UAV swarms" (``papers/dmpc-swarm-mlr-dmpc.txt``). Its Sec. 5.1 gives
the round T = 0.2 s (5 Hz) and a third-order integrator with jerk input
(Sec. 4.1); the rest of the numbers are not in the paper and are marked
"chosen" with the reason.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.limits import KinematicLimits, require_finite_jerk
from sim.checks import (
    ConfigError,
    require_at_least,
    require_boolean,
    require_box,
    require_instance,
    require_integer_at_least,
    require_non_negative,
    require_positive,
)

__all__ = ["MlrConfig", "TRIGGERS"]

TRIGGERS = ("rr", "db", "ht")


@dataclass(frozen=True)
class MlrConfig:
    """Settings shared by the compute units (CUs), the UAVs and the QP (Eq. 13a-13f).

    All positions are in the world frame (z up) in [m]. The nominal model is
    the 3-D triple integrator of :mod:`planners.dmpc.model` (state
    ``[p, v, a]`` (9,), input jerk (3,)), the paper's f̂_i (Sec. 4.1).

    Attributes:
        n_uavs: N, number of UAVs (the QP is sized for N - 1 others).
        n_cus: M, number of compute units, 1 <= M < N (Sec. 1.1: M < N).
        round_s: T, the round of computation + communication in [s]
            (Sec. 5.1: 0.2 s, 5 Hz).
        horizon_rounds: H, prediction horizon in rounds; a trajectory lasts
            H T [s] (chosen: 15, 3 s, as our DMPC's K h).
        input_steps_per_round: T / T_s, the piecewise-constant jerk inputs per
            round (Eq. 12; the paper requires T / T_s = h_s / H). Chosen: 1
            (T_s = 0.2 s, h_s = 15 inputs, 45 variables).
        collision_checks_per_round: T / T_c, BVC check times per round
            (Eq. 13f; h_c = H T / T_c). Must be a multiple of
            ``input_steps_per_round``. Chosen: 1 (T_c = 0.2 s); the gap
            between checks is covered by the margin of ``d_hat_min_m`` over
            the collision distance (Theorem 3, Delta d_min,cont; see
            :mod:`mpcde.evals.mlr_swarm`).
        d_hat_min_m: d̂_min, minimum ellipsoidal distance between reference
            positions at the check times in [m] (Eq. 15; Sec. 5.1 uses 0.25 m
            for Crazyflies. Chosen: 0.45 m, so that straight-line motion at
            the speed limits keeps >= 0.25 m between checks 0.2 s apart).
        bvc_margin_m: m added to d̂_min in the BVC rows of the QP [m]
            (chosen 0.005, above OSQP's tolerance, so that solutions met only
            to tolerance still keep d̂_min; see :func:`planners.dmpc.mlr.qp.time_varying_bvc`).
        downwash: c >= 1 of Theta = diag(1, 1, c) (Eq. 2; chosen: 1.5).
        limits: per-axis limits (:class:`planners.limits.KinematicLimits`):
            speed |v| <= ``v_max_mps`` [m/s] (X̂, Eq. 13d; chosen: 1.0),
            acceleration ``a_max_mps2`` [m/s^2] (X̂; chosen: 3.0) and jerk
            |u| <= ``j_max_mps3`` [m/s^3] (Û, Eq. 13c; chosen: 10).
        pos_min_world: (3,) lower corner of the flying space in [m] (X̂;
            chosen: a 6 m x 6 m hall, 0.2 m above the ground).
        pos_max_world: (3,) upper corner in [m] (chosen: 2.8 m high).
        weight_pos: Q on position error in [1/m^2] (Eq. 13a; chosen 1).
        weight_vel: Q on velocity (target velocity 0) in [s^2/m^2] (chosen 0.2).
        weight_acc: Q on acceleration in [s^4/m^2] (chosen 0.05).
        weight_jerk: R on the jerk input in [s^6/m^2] (chosen 0.01; smaller
            weights on v, a and jerk need more OSQP iterations:
            docs/results/mlr_dmpc.md#qp-weights-tolerance-and-form).
        max_candidates: most trajectories a non-deprecated tracker can hold
            (old + new one: 2, Lemma 1); the QP is sized for
            (N - 1) x ``max_candidates`` x h_c BVC rows.
        max_kept_deprecated: a deprecated tracker keeps at most this many
            candidates (the newest), so that a later UAV state message naming
            one of them restores it (chosen: 8).
        lazy_recovery: how a CU whose trackers are deprecated picks its
            recovery request (Alg. 1 Lines 22-32; the paper does not say which
            UAV to ask). True (chosen): it asks first for a UAV whose state
            message named a trajectory the tracker lacks (only a reply can
            restore it); it does not ask for a UAV another CU asked for in the
            previous round (that UAV's reply comes in this round); and when every
            deprecated tracker became deprecated in this round only for want of
            metadata or of a CU message, it waits one round (a CU message with
            its priorities and no trajectory) for the UAVs' next state messages,
            which restore such trackers without a request. False: it asks at
            once for the deprecated UAV at rank (k + w) mod (number deprecated)
            and donates its next slot. Either way it computes nothing while a
            tracker is deprecated, so the choice only affects progress, never
            safety (:mod:`planners.dmpc.mlr.compute_unit`).
        precise_cu_loss: what a lost CU message deprecates (Alg. 2 Line 18).
            False: every tracker (the paper: "it might lack the actual
            trajectory of an unknown UAV"). True (chosen): when this CU heard
            every CU slot of round k - 2, its A_ET(k - 1) is the A_ET(k - 1)
            of every CU that computed in round k - 1 (the same priority
            vectors; Eq. 15's midway / relaxed choice already rests on this),
            so the lost message of CU v can only have carried a trajectory for
            the UAV at rank (k - 1 + v) mod M of it: only that tracker is
            deprecated. Otherwise every tracker is, as in the paper.
        keep_ambiguous: what a lost UAV state message does to a tracker that
            holds the UAV's old and new trajectory (Alg. 2 Line 13). False:
            deprecated, as in the paper. True (chosen): the tracker keeps both
            candidates, not deprecated, until a state message names one (or
            a third candidate arrives: then deprecated). Both candidates stay
            in every QP, so the true trajectory is always among the
            constrained ones (Lemma 1 holds); Lemma 2's equality across CUs
            becomes inclusion, which keeps Theorem 3's argument
            (:mod:`planners.dmpc.mlr.tracker`, step 2b).
        repeat_trajectory: a CU's message of round k also carries the
            trajectory it computed in round k - 1 (``CuTrajectoryMessage.
            repeat_trajectory``). A CU that lost the round k - 1 message adds
            it to that UAV's deprecated tracker one round late, where the
            UAV's state message of round k, which names the trajectory it
            follows, restores the tracker (Alg. 2 step 1) without a recovery
            request and a donated slot. Not in DMPC-Swarm (a protocol change:
            the CU message carries two trajectories); it only adds candidates
            to deprecated trackers, so Lemma 1 and the collision argument are
            untouched (:mod:`planners.dmpc.mlr.tracker`, step 0). Measured:
            docs/results/mlr_dmpc.md#the-16-uav-swap-under-loss-with-every-default.
        soft_rotation: the Appendix's B4 soft constraint: every BVC row of
            another trajectory is tightened by a slack eps >= 0 that the cost
            rewards (linear reward, small quadratic), more for a UAV to the
            right, so that approaching UAVs turn around each other. With
            eps = 0 the rows are Eq. 15's, so Theorem 1's shifted trajectory
            stays feasible and the guarantees hold (the paper, after Chen et
            al. 2023). Chosen on: docs/results/mlr_dmpc.md#what-each-measure-adds.
        soft_weight: reward per metre of slack, other UAV not to the right
            [1/m] (chosen 0.5).
        soft_weight_right: the same for a UAV to the right [1/m] (chosen 2.0).
        soft_weight_quadratic: quadratic cost on the slack [1/m^2] (chosen 1.0).
        soft_max_m: upper bound of the slack [m] (chosen 0.3).
        arrived_m: a UAV this close to its target has arrived: neither
            deadlock measure (``deadlock_trigger``) counts it as
            held [m] (chosen 0.1).
        deadlock_trigger: Appendix A's deadlock-aware triggering: a UAV held
            away from its target by a trajectory computed within the last
            ``deadlock_rounds`` rounds (planned motion < ``deadlock_motion_m``)
            gets priority 1, so the CUs compute UAVs that can move.
        deadlock_motion_m: planned motion below which a trajectory holds its
            UAV [m] (chosen 0.02).
        deadlock_rounds: how long such a trajectory lowers the priority
            [rounds] (chosen 40: 8 s, docs/results/mlr_dmpc.md#what-each-measure-adds).
        trigger: event trigger of Appendix A: ``"rr"`` (round-robin, A1),
            ``"db"`` (distance-based, A2) or ``"ht"`` (hybrid, A3).
        priority_scale_rr: one 8-bit priority unit of RR in rounds (chosen 1).
        priority_scale_db_m: one unit of DB in [m] (chosen 0.02: 255 = 5.1 m).
        priority_scale_ht: one unit of HT in [m x rounds] (chosen 0.1).
        osqp_eps_abs: OSQP absolute tolerance (chosen 1e-3: several times
            fewer iterations than 1e-4, and the BVC rows are still met well
            within d̂_min - d_min; docs/results/mlr_dmpc.md#qp-weights-tolerance-and-form; the terminal halt
            is made exact afterwards, see :class:`planners.dmpc.mlr.qp.MlrProblem`).
        osqp_eps_rel: OSQP relative tolerance (chosen 1e-3).
        osqp_max_iter: OSQP iteration limit (chosen 20000).
        osqp_polish: OSQP polishing (chosen False).
    """

    n_uavs: int = 16
    n_cus: int = 3
    round_s: float = 0.2
    horizon_rounds: int = 15
    input_steps_per_round: int = 1
    collision_checks_per_round: int = 1
    d_hat_min_m: float = 0.45
    bvc_margin_m: float = 0.005
    downwash: float = 1.5
    limits: KinematicLimits = KinematicLimits(1.0, 3.0, 10.0)
    pos_min_world: tuple[float, float, float] = (-3.0, -3.0, 0.2)
    pos_max_world: tuple[float, float, float] = (3.0, 3.0, 2.8)
    weight_pos: float = 1.0
    weight_vel: float = 0.2
    weight_acc: float = 0.05
    weight_jerk: float = 0.01
    max_candidates: int = 2
    max_kept_deprecated: int = 8
    lazy_recovery: bool = True
    precise_cu_loss: bool = True
    keep_ambiguous: bool = True
    repeat_trajectory: bool = True
    soft_rotation: bool = True
    soft_weight: float = 0.5
    soft_weight_right: float = 2.0
    soft_weight_quadratic: float = 1.0
    soft_max_m: float = 0.3
    arrived_m: float = 0.1
    deadlock_trigger: bool = True
    deadlock_motion_m: float = 0.02
    deadlock_rounds: int = 40
    trigger: str = "ht"
    priority_scale_rr: float = 1.0
    priority_scale_db_m: float = 0.02
    priority_scale_ht: float = 0.1
    osqp_eps_abs: float = 1e-3
    osqp_eps_rel: float = 1e-3
    osqp_max_iter: int = 20000
    osqp_polish: bool = False

    def __post_init__(self) -> None:
        require_integer_at_least("n_uavs", self.n_uavs, 2)
        require_integer_at_least("n_cus", self.n_cus, 1)
        if self.n_cus >= self.n_uavs:
            raise ConfigError("n_cus", self.n_cus, f"an integer < n_uavs={self.n_uavs} (M < N)")
        require_positive("round_s", self.round_s)
        require_integer_at_least("horizon_rounds", self.horizon_rounds, 2)
        require_integer_at_least("input_steps_per_round", self.input_steps_per_round, 1)
        require_integer_at_least("collision_checks_per_round", self.collision_checks_per_round, 1)
        if self.collision_checks_per_round % self.input_steps_per_round:
            allowed = f"a multiple of input_steps_per_round={self.input_steps_per_round}"
            raise ConfigError("collision_checks_per_round", self.collision_checks_per_round, allowed)
        require_instance("limits", self.limits, KinematicLimits)
        require_finite_jerk(self.limits, "the jerk is the input (Eq. 13c)")
        for name in ("d_hat_min_m", "weight_pos"):
            require_positive(name, getattr(self, name))
        for name in ("weight_vel", "weight_acc", "weight_jerk", "bvc_margin_m"):
            require_non_negative(name, getattr(self, name))
        require_at_least("downwash", self.downwash, 1.0)
        require_box("pos_min_world", self.pos_min_world, "pos_max_world", self.pos_max_world)
        require_integer_at_least("max_candidates", self.max_candidates, 1)
        require_integer_at_least("max_kept_deprecated", self.max_kept_deprecated, 1)
        require_boolean("lazy_recovery", self.lazy_recovery)
        require_boolean("precise_cu_loss", self.precise_cu_loss)
        require_boolean("keep_ambiguous", self.keep_ambiguous)
        require_boolean("repeat_trajectory", self.repeat_trajectory)
        require_boolean("soft_rotation", self.soft_rotation)
        for name in ("soft_weight", "soft_weight_right"):
            require_non_negative(name, getattr(self, name))
        for name in ("soft_weight_quadratic", "soft_max_m"):
            require_positive(name, getattr(self, name))
        require_positive("arrived_m", self.arrived_m)
        require_boolean("deadlock_trigger", self.deadlock_trigger)
        require_positive("deadlock_motion_m", self.deadlock_motion_m)
        require_integer_at_least("deadlock_rounds", self.deadlock_rounds, 1)
        if self.trigger not in TRIGGERS:
            raise ConfigError("trigger", self.trigger, f"one of {', '.join(TRIGGERS)}")
        for name in ("priority_scale_rr", "priority_scale_db_m", "priority_scale_ht", "osqp_eps_abs", "osqp_eps_rel"):
            require_positive(name, getattr(self, name))
        require_integer_at_least("osqp_max_iter", self.osqp_max_iter, 1)
        require_boolean("osqp_polish", self.osqp_polish)

    @property
    def input_step_s(self) -> float:
        """T_s = T / (T / T_s) in [s]."""
        return self.round_s / self.input_steps_per_round

    @property
    def n_inputs(self) -> int:
        """h_s, number of piecewise-constant inputs of a trajectory (H T / T_s)."""
        return self.horizon_rounds * self.input_steps_per_round

    @property
    def check_step_s(self) -> float:
        """T_c in [s]."""
        return self.round_s / self.collision_checks_per_round

    @property
    def n_checks(self) -> int:
        """h_c, number of BVC check times of a trajectory (H T / T_c)."""
        return self.horizon_rounds * self.collision_checks_per_round

    @property
    def horizon_s(self) -> float:
        """H T in [s]."""
        return self.horizon_rounds * self.round_s

    @property
    def theta_inv_diag(self) -> np.ndarray:
        """(3,) diagonal of Theta^-1 = diag(1, 1, 1/c) (Eq. 2)."""
        return np.array([1.0, 1.0, 1.0 / self.downwash])
