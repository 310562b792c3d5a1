"""What one ADMM agent's rounds did, for its ``metrics.json`` entry."""

from __future__ import annotations

from dataclasses import dataclass, field

__all__ = ["AdmmRoundStats"]


@dataclass
class AdmmRoundStats:
    """What one agent's ADMM did (for :meth:`AdmmAgent.extra_metrics`).

    Attributes:
        steps: MPC steps completed with a plan.
        aborted_steps: steps started and not completed (a failed local QP, a
            missed sub-round).
        iterations: ADMM iterations of the completed steps.
        qp_failures: local QPs OSQP did not solve.
        skipped_rounds: sub-rounds in which ``outgoing`` was not called.
        copies_received: neighbours' copies of this drone's trajectory received in their sub-round.
        copies_missing: expected copies that did not come (left out of the average).
        means_received: neighbours' means received in their sub-round.
        means_missing: expected means that did not come (Step 8 skipped on that copy).
        not_averaged: means received that left this drone's copy out (its copy was lost).
        resolved_means: missed means resolved from a later bundle of their owner
            (rule 2): the skipped Step 8 term added, or none due (the mean left
            this drone's copy out, or was never computed).
        unresolved_means: missed means not resolved within the window.
        late_messages: bundles addressed to this drone that came after their sub-round.
        state_resets: steps started from the estimate because it disagreed with the plan.
        max_reference_jump_m: largest jump of the reference when a new plan took over [m].
        qp_solve_s: every local QP's wall time [s] (Step 3).
        admm_s: per completed step, the drone's ADMM compute time [s].
        osqp_iterations: every local QP's OSQP iterations.
        osqp_max_iter_hits: local QPs stopped at ``osqp_max_iter``.
        primal_residual: per completed step, ||z_i - zbar_i|| of its last iteration [m].
        max_slack: largest soft-constraint slack of a plan.
    """

    steps: int = 0
    aborted_steps: int = 0
    iterations: int = 0
    qp_failures: int = 0
    skipped_rounds: int = 0
    copies_received: int = 0
    copies_missing: int = 0
    means_received: int = 0
    means_missing: int = 0
    not_averaged: int = 0
    resolved_means: int = 0
    unresolved_means: int = 0
    late_messages: int = 0
    state_resets: int = 0
    max_reference_jump_m: float = 0.0
    qp_solve_s: list[float] = field(default_factory=list)
    admm_s: list[float] = field(default_factory=list)
    osqp_iterations: list[int] = field(default_factory=list)
    osqp_max_iter_hits: int = 0
    primal_residual: list[float] = field(default_factory=list)
    max_slack: float = 0.0

