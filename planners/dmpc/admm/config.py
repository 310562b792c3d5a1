"""Configuration of the cooperative formation DMPC solved by decentralized ADMM (:class:`AdmmFormationConfig`).

The paper is Stomberg, Ebel, Faulwasser, Eberhard, "Cooperative Distributed MPC
via Decentralized Real-Time Optimization: Implementation Results for Robot
Formations" (``papers/admm-dsqp-formation-dmpc.txt``). Its Sec. 5.1 gives
rho = 1, l_max = 5, h = 0.2 s and P = Q (terminal weight equal to the stage
weight); its robots are single integrators with velocity inputs. Ours are the
double integrators of :mod:`planners.dmpc.model` (acceleration input), with K
and h from our DMPC (:class:`planners.dmpc.config.DmpcConfig`). Values without a
source are marked "chosen" and say why.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planners.limits import KinematicLimits, require_infinite_jerk
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

__all__ = ["AdmmFormationConfig"]


@dataclass(frozen=True)
class AdmmFormationConfig:
    """Settings of the formation OCP (paper Eq. 1) and of its ADMM solution (Eq. 4a-4c, Algorithm 2).

    All positions are in the world frame (ENU, z up) in [m]. The OCP of drone
    i over k = 1..K (the k = 0 terms are constants: p[0] is measured) is::

        sum_k w_g[k] ||p_i[k] - r_i[k]||^2 + sum_{k=0}^{K-1} r ||u_i[k]||^2 + c s_i^2
        + sum_{edges (i,j)} sum_k w_f[k] ||(p_i[k] - p_j[k]) - d_ij||^2

    with w_g[k] = ``weight_tracking`` (k < K), ``weight_terminal_tracking``
    (k = K), and w_f likewise; see :mod:`planners.dmpc.admm.ocp`.

    Attributes:
        horizon_steps: K, number of prediction steps (our DMPC: 15; the paper
            uses N = 7 for velocity-controlled robots).
        step_s: h, prediction step and MPC sampling interval in [s] (paper
            Sec. 5.1: 0.2 s).
        model: prediction model of :mod:`planners.dmpc.model`; only
            ``"double"`` (state [p, v], input acceleration u [m/s^2]) is
            supported (chosen: the paper's coupling is on positions only, and
            the double integrator is what the rest of our DMPC flies).
        weight_formation: q_f on ||(p_i[k] - p_j[k]) - d_ij||^2 per edge and
            step k < K, in [1/m^2] (paper: Q_ij = -10 against the tracking
            weight 10, i.e. as strong as tracking; chosen: 10, ten times the
            tracking weight, so that the drones close the formation before
            they converge on their references).
        weight_tracking: q_g on ||p_i[k] - r_i[k]||^2, each drone's own
            reference, k < K, in [1/m^2] (chosen: 1).
        weight_input: r on ||u_i[k]||^2 in [s^4/m^2] (paper: R_ii = 1 on
            velocities; chosen: 0.1: with q_g = 1 a scattered formation closes
            within seconds in ``bench_admm.py``; the input box, not r, limits
            the first steps; docs/results/admm_formation.md#figures-quoted-in-other-docstrings).
        weight_terminal_formation: q_f at k = K in [1/m^2] (paper: P = Q, so
            the same as ``weight_formation``).
        weight_terminal_tracking: q_g at k = K in [1/m^2] (paper: P = Q).
        weight_slack: c on c s_i^2, one slack per drone shared by all soft
            state constraints (paper Remark 2: c >> 0). The slack is in [m]
            on position rows and [m/s] on velocity rows, so c is in [1/m^2]
            or [s^2/m^2] respectively (chosen: 1e4; a violation of 1 cm costs
            as much as 1 m of tracking error).
        pos_min_world: (3,) lower corner of the soft position box [m]
            (chosen: our DMPC's 40 m x 40 m arena, 0.2 m above the ground).
        pos_max_world: (3,) upper corner of the soft position box [m].
        limits: per-axis limits (:class:`planners.limits.KinematicLimits`): soft
            speed |v| <= ``v_max_mps`` + s [m/s] (our DMPC: 2) and hard input
            |u| <= ``a_max_mps2`` [m/s^2] (our DMPC and on-demand DMPC Sec. 4: 4);
            ``j_max_mps3`` must be inf (the input is the acceleration).
        rho: ADMM penalty parameter rho (Eq. 4a, 4c), in the cost's units per
            squared decision variable (paper Sec. 5.1: 1, tuned in
            {0.1, 1, 10, 100}; kept after the same sweep on our OCP,
            docs/results/admm_formation.md#figures-quoted-in-other-docstrings).
        l_max: ADMM iterations per MPC step (paper Sec. 5.1: 5); with dSQP,
            per SQP iteration (Algorithm 3 Step 5; Sec. 5.2: 3).
        solver: ``"admm"`` (Algorithm 2: the convex OCP, no coupled
            constraints) or ``"dsqp"`` (Algorithm 3: an outer SQP whose QPs
            ADMM solves, with the minimum-distance constraints of Eq. 8
            between neighbours, :mod:`planners.dmpc.admm.distance`).
        sqp_iterations: q_max, dSQP's outer iterations per MPC step (Sec. 5.2: 5).
        d_min_m: d of Eq. 8, the minimum ellipsoidal distance between
            neighbours' planned positions [m] (Sec. 5.2: 0.4 m).
        downwash: c >= 1 of Theta = diag(1, 1, c) in the distance (DMPC-Swarm
            Eq. 2; 1 is the paper's Euclidean norm; chosen 2.0, our DMPC's).
        distance_rows: what a drone's distance rows constrain: ``"copies"``
            (QP (6c) as published: its own positions and its copy of the
            neighbour's) or ``"means"`` (its own positions against the
            neighbour's latest consensus mean, a constant;
            :mod:`planners.dmpc.admm.distance`; chosen: on the four-drone swap
            the paper's rows kept no rho both safe and arriving, these did at
            rho = 1: docs/results/admm_formation.md#dsqp-rows-screen).
        delay_compensation: paper Remark 1: u_i[0] is fixed to the input that
            is already being applied on [t, t + h) (decided in the previous
            step) and the step decides u_i[1], applied from t + h, so the
            whole ADMM round may take up to h. False optimises u_i[0] too
            (for a loop that waits for the round before applying it).
        warm_start: start each MPC step's ADMM from the previous step's zbar
            and gamma shifted by one step (paper Sec. 5.1); False starts every
            step cold (gamma = 0, zbar = free response), for comparison.
        osqp_eps_abs: OSQP absolute tolerance of each local QP (Step 3)
            (chosen: 1e-4, as our DMPC's QP: as close to the centralized
            optimum as tighter tolerances, because each ADMM iteration
            warm-starts OSQP and the inexactness does not accumulate;
            docs/results/admm_formation.md#figures-quoted-in-other-docstrings).
        osqp_eps_rel: OSQP relative tolerance of each local QP (chosen: 1e-4).
        osqp_max_iter: OSQP iteration limit of one local QP (chosen: 4000);
            a local QP that reaches it is used as it is and counted in
            ``AdmmStepResult.osqp_max_iter_hits``.
        osqp_adaptive_rho: OSQP's own adaptive step size inside a local QP
            (not the ADMM rho above). Each adaptation refactorises OSQP's KKT
            matrix; ``AdmmStepResult.osqp_rho_updates`` counts them (chosen:
            False: with ``osqp_rho`` = 1 the local QPs converge about as fast
            without it, and then no solve ever refactorises;
            docs/results/admm_formation.md#figures-quoted-in-other-docstrings).
        osqp_rho: OSQP's own step size inside a local QP, fixed when
            ``osqp_adaptive_rho`` is False (chosen: 1; with OSQP's default
            0.1 single local QPs of the closed loop needed thousands of
            iterations; docs/results/admm_formation.md#figures-quoted-in-other-docstrings).
    """

    horizon_steps: int = 15
    step_s: float = 0.2
    model: str = "double"
    weight_formation: float = 10.0
    weight_tracking: float = 1.0
    weight_input: float = 0.1
    weight_terminal_formation: float = 10.0
    weight_terminal_tracking: float = 1.0
    weight_slack: float = 1.0e4
    pos_min_world: tuple[float, float, float] = (-20.0, -20.0, 0.2)
    pos_max_world: tuple[float, float, float] = (20.0, 20.0, 10.0)
    limits: KinematicLimits = KinematicLimits(2.0, 4.0)
    rho: float = 1.0
    l_max: int = 5
    solver: str = "admm"
    sqp_iterations: int = 5
    d_min_m: float = 0.4
    downwash: float = 2.0
    distance_rows: str = "means"
    delay_compensation: bool = True
    warm_start: bool = True
    osqp_eps_abs: float = 1e-4
    osqp_eps_rel: float = 1e-4
    osqp_max_iter: int = 4000
    osqp_adaptive_rho: bool = False
    osqp_rho: float = 1.0

    def __post_init__(self) -> None:
        require_integer_at_least("horizon_steps", self.horizon_steps, 2)
        require_positive("step_s", self.step_s)
        if self.model != "double":
            raise ConfigError("model", self.model, "only 'double' (the formation ADMM couples positions only)")
        for name in ("weight_formation", "weight_terminal_formation", "weight_tracking", "weight_terminal_tracking"):
            require_non_negative(name, getattr(self, name))
        require_positive("weight_input", self.weight_input)
        require_positive("weight_slack", self.weight_slack)
        require_box("pos_min_world", self.pos_min_world, "pos_max_world", self.pos_max_world)
        require_instance("limits", self.limits, KinematicLimits)
        require_infinite_jerk(self.limits, "the double integrator's input is the acceleration")
        require_positive("rho", self.rho)
        require_integer_at_least("l_max", self.l_max, 1)
        if self.solver not in ("admm", "dsqp"):
            raise ConfigError("solver", self.solver, "one of admm, dsqp")
        require_integer_at_least("sqp_iterations", self.sqp_iterations, 1)
        require_positive("d_min_m", self.d_min_m)
        require_at_least("downwash", self.downwash, 1.0)
        if self.distance_rows not in ("copies", "means"):
            raise ConfigError("distance_rows", self.distance_rows, "one of copies, means")
        require_boolean("delay_compensation", self.delay_compensation)
        require_boolean("warm_start", self.warm_start)
        require_positive("osqp_eps_abs", self.osqp_eps_abs)
        require_positive("osqp_eps_rel", self.osqp_eps_rel)
        require_integer_at_least("osqp_max_iter", self.osqp_max_iter, 1)
        require_boolean("osqp_adaptive_rho", self.osqp_adaptive_rho)
        require_positive("osqp_rho", self.osqp_rho)

    @property
    def iterations_per_step(self) -> int:
        """ADMM iterations of one MPC step: l_max, or q_max l_max with dSQP."""
        return self.l_max * (self.sqp_iterations if self.solver == "dsqp" else 1)

    @property
    def horizon_s(self) -> float:
        """Prediction horizon K h in [s]."""
        return self.horizon_steps * self.step_s

    def tracking_weights(self) -> np.ndarray:
        """(K,) w_g[k] for p[k], k = 1..K: stage weight, terminal weight at k = K (paper: P = Q)."""
        w = np.full(self.horizon_steps, float(self.weight_tracking))
        w[-1] = self.weight_terminal_tracking
        return w

    def formation_weights(self) -> np.ndarray:
        """(K,) w_f[k] for the edge terms at k = 1..K (terminal weight at k = K)."""
        w = np.full(self.horizon_steps, float(self.weight_formation))
        w[-1] = self.weight_terminal_formation
        return w
