"""A reference trajectory of MLR-DMPC: piecewise-constant jerk from an initial state (DMPC-Swarm Eq. 12).

    û(t) = sum_{kappa=0}^{h_s-1} Gamma_Ts(t - t_start - kappa T_s) u_kappa,

applied to the triple integrator ``x = [p, v, a]`` (world frame, z up) from
``x0`` at ``t_start``. After the last input (t >= t_start + h_s T_s) the input
is zero: with the terminal halt of Eq. 13e the trajectory then hovers at its
last position (for a trajectory without the halt the integrator simply coasts
with its final acceleration, the same nominal model).

A trajectory is identified by its metadata :class:`TrajectoryId` (the round in
which it was computed and the CU that computed it; Sec. 4.2.1), which is what
UAVs broadcast instead of the trajectory itself.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from planners.dmpc.model import rollout
from planners.dmpc.types import freeze_array

__all__ = ["ReferenceTrajectory", "TrajectoryId", "positions_at_each"]


@dataclass(frozen=True, order=True)
class TrajectoryId:
    """Metadata of a trajectory (Sec. 4.2.1: "the calculation time and the responsible CU").

    Attributes:
        calc_round: round k in which a CU computed it (it is followed from
            round k + 1 on); -1 for the initial hover trajectories (Remark 2).
        cu_id: index w in 0..M-1 of the CU that computed it; -1 for initial ones.
    """

    calc_round: int
    cu_id: int


def _frozen(obj: object, name: str, shape_tail: tuple[int, ...]) -> np.ndarray:
    """Field ``name`` of ``obj`` as a read-only finite float array whose shape ends in ``shape_tail``."""

    def valid(arr: np.ndarray) -> bool:
        return arr.shape[arr.ndim - len(shape_tail):] == shape_tail and bool(np.all(np.isfinite(arr)))

    return freeze_array(obj, name, float, valid, f"finite (..., {shape_tail})", label=name)


@dataclass(frozen=True)
class ReferenceTrajectory:
    """x̂(t), û(t) of one UAV: initial state plus piecewise-constant jerk (Eq. 12).

    Attributes:
        meta: its :class:`TrajectoryId`.
        t_start_s: absolute time [s] of ``x0`` (for a trajectory computed in
            round k: (k + 1) T, one round of latency, Eq. 13b).
        x0: (9,) initial state ``[p (3), v (3), a (3)]`` in [m, m/s, m/s^2].
        inputs: (h_s, 3) jerk u_kappa [m/s^3] on [t_start + kappa T_s, t_start + (kappa + 1) T_s).
        input_step_s: T_s [s].
        knots: (h_s + 1, 9) states at the input switching times (derived).
    """

    meta: TrajectoryId
    t_start_s: float
    x0: np.ndarray
    inputs: np.ndarray
    input_step_s: float
    knots: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        x0 = _frozen(self, "x0", (9,))
        inputs = _frozen(self, "inputs", (3,))
        if inputs.ndim != 2:
            raise ValueError(f"inputs shape {inputs.shape}: expected (h_s, 3)")
        if not self.input_step_s > 0:
            raise ValueError(f"input_step_s={self.input_step_s!r}: a finite number > 0")
        knots = rollout("triple", self.input_step_s, x0, inputs)
        knots.setflags(write=False)
        object.__setattr__(self, "knots", knots)

    @classmethod
    def hover(cls, meta: TrajectoryId, t_start_s: float, pos_world: np.ndarray, n_inputs: int,
              input_step_s: float) -> "ReferenceTrajectory":
        """Hold ``pos_world`` (3,) [m] with zero velocity, acceleration and jerk (Remark 2)."""
        x0 = np.zeros(9)
        x0[:3] = np.asarray(pos_world, float).reshape(3)
        return cls(meta, float(t_start_s), x0, np.zeros((int(n_inputs), 3)), float(input_step_s))

    @property
    def t_end_s(self) -> float:
        """End of the last input [s]; afterwards the input is zero."""
        return self.t_start_s + self.inputs.shape[0] * self.input_step_s

    def states_at(self, times_s: np.ndarray) -> np.ndarray:
        """x̂(t) at absolute times ``times_s`` (n,) -> (n, 9), exact under Eq. 12.

        Raises:
            ValueError: a time before ``t_start_s`` (the trajectory does not exist then).
        """
        t = np.atleast_1d(np.asarray(times_s, float))
        tau_all = t - self.t_start_s
        if np.any(tau_all < -1e-9):
            raise ValueError(f"times_s: min {t.min()!r} before t_start_s={self.t_start_s!r}")
        h_s, Ts = self.inputs.shape[0], self.input_step_s
        idx = np.clip(np.floor(tau_all / Ts + 1e-9).astype(int), 0, h_s)
        tau = np.maximum(tau_all - idx * Ts, 0.0)[:, None]
        j = np.vstack([self.inputs, np.zeros((1, 3))])[idx]  # zero input after the horizon
        return _from_knots(self.knots[idx], j, tau)

    def positions_at(self, times_s: np.ndarray) -> np.ndarray:
        """p̂(t) at ``times_s`` (n,) -> (n, 3) [m]."""
        return self.states_at(times_s)[:, :3]


def positions_at_each(trajectories: "list[ReferenceTrajectory]", times_s: np.ndarray) -> np.ndarray:
    """p̂_n(t_n): trajectory n at its own time t_n, for all n at once -> (n, 3) [m].

    The same Eq. 12 evaluation as :meth:`ReferenceTrajectory.positions_at`,
    batched across trajectories (the event trigger needs one position per UAV
    each round; one call per UAV costs far more: docs/results/mlr_dmpc.md#qp-weights-tolerance-and-form).

    Args:
        trajectories: n trajectories (any input steps and lengths).
        times_s: (n,) absolute times [s], each at or after its trajectory's ``t_start_s``.
    """
    t = np.asarray(times_s, float).reshape(-1)
    if t.size != len(trajectories):
        raise ValueError(f"times_s: {t.size} times for {len(trajectories)} trajectories")
    if not trajectories:
        return np.zeros((0, 3))
    t0 = np.array([tr.t_start_s for tr in trajectories])
    step = np.array([tr.input_step_s for tr in trajectories])
    n_in = np.array([tr.inputs.shape[0] for tr in trajectories])
    tau_all = t - t0
    if np.any(tau_all < -1e-9):
        raise ValueError(f"times_s: a time before its trajectory's t_start_s (by {-tau_all.min()!r} s)")
    idx = np.clip(np.floor(tau_all / step + 1e-9).astype(int), 0, n_in)
    tau = np.maximum(tau_all - idx * step, 0.0)[:, None]
    x = np.array([tr.knots[i] for tr, i in zip(trajectories, idx)])
    j = np.array([tr.inputs[i] if i < tr.inputs.shape[0] else np.zeros(3) for tr, i in zip(trajectories, idx)])
    return _from_knots(x, j, tau)[:, :3]


def _from_knots(x: np.ndarray, j: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """States (n, 9) a time tau (n, 1) [s] after knot states x (n, 9) under constant jerk j (n, 3) (Eq. 12)."""
    p, v, a = x[:, :3], x[:, 3:6], x[:, 6:9]
    out = np.empty((x.shape[0], 9))
    out[:, :3] = p + v * tau + a * tau**2 / 2.0 + j * tau**3 / 6.0
    out[:, 3:6] = v + a * tau + j * tau**2 / 2.0
    out[:, 6:9] = a + j * tau
    return out
