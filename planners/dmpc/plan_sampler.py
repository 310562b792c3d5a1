"""Fast scalar evaluation of one DMPC plan at the controller's rate (position, velocity, acceleration)."""

from __future__ import annotations

import math

import numpy as np

from planners.dmpc.types import DmpcPlan

__all__ = ["PlanSampler", "sample_or_hover"]


class PlanSampler:
    """Fast scalar evaluation of a :class:`DmpcPlan` for the 240 Hz reference.

    The plan's cubic Hermite pieces (:mod:`planners.dmpc.types`) are turned
    into power-basis coefficients once per plan, p_i(s) = c0 + c1 s + c2 s^2 +
    c3 s^3 with s = (t - t_i) / h in [0, 1); the tails are constant velocity.
    Same values as :meth:`DmpcPlan.position` / ``velocity`` / ``acceleration``
    (right limits at the samples), at a fraction of their cost per call.

    Args:
        plan: the plan to sample.
    """

    def __init__(self, plan: DmpcPlan) -> None:
        p, v, h = plan.pos_world, plan.vel_world, plan.h_s
        p0, p1, v0, v1 = p[:-1], p[1:], v[:-1] * h, v[1:] * h
        # Hermite -> power basis: c0 = p0, c1 = h v0, c2 = 3(p1 - p0) - 2 h v0 - h v1, c3 = 2(p0 - p1) + h v0 + h v1
        self.coef = np.stack([p0, v0, 3 * (p1 - p0) - 2 * v0 - v1, 2 * (p0 - p1) + v0 + v1], axis=1)  # (K, 4, 3)
        self.plan = plan
        self.t0_s, self.h_s, self.K = plan.t0_s, h, plan.horizon_steps

    def sample(self, time_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position [m], velocity [m/s], acceleration [m/s^2], each (3,), at ``time_s`` [s]."""
        plan, h = self.plan, self.h_s
        u = (time_s - self.t0_s) / h
        if u < 0.0:
            return plan.pos_world[0] + plan.vel_world[0] * (time_s - self.t0_s), plan.vel_world[0].copy(), np.zeros(3)
        if u >= self.K:
            return plan.pos_world[-1] + plan.vel_world[-1] * (time_s - plan.t_end_s), plan.vel_world[-1].copy(), np.zeros(3)
        i = min(int(math.floor(u + 1e-9)), self.K - 1)
        s = min(max(u - i, 0.0), 1.0)
        c0, c1, c2, c3 = self.coef[i]
        pos = c0 + s * (c1 + s * (c2 + s * c3))
        vel = (c1 + s * (2.0 * c2 + 3.0 * s * c3)) / h
        acc = (2.0 * c2 + 6.0 * s * c3) / (h * h)
        return pos, vel, acc


def sample_or_hover(
    sampler: PlanSampler | None, start_world: np.ndarray | None, time_s: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Position [m], velocity [m/s], acceleration [m/s^2] (3,) of ``sampler``'s plan at ``time_s`` [s].

    Before the first plan (``sampler`` None): a hover at ``start_world`` (the origin before any estimate).
    """
    if sampler is None:
        pos = start_world if start_world is not None else np.zeros(3)
        return np.array(pos, float), np.zeros(3), np.zeros(3)
    return sampler.sample(time_s)

