"""Prediction model of the DMPC QP: P = A0 x0 + Lambda U (on-demand DMPC Eq. 10).

Each axis is an integrator chain sampled with a zero-order hold on the input
(step h). Per axis, with the scalar state s and input w:

* double integrator (on-demand DMPC Eq. 6): s = [p, v], w = a,
  A1 = [[1, h], [0, 1]],  B1 = [h^2/2, h]^T;
* triple integrator: s = [p, v, a], w = j (jerk),
  A1 = [[1, h, h^2/2], [0, 1, h], [0, 0, 1]],  B1 = [h^3/6, h^2/2, h]^T.

The 3-D model is A = kron(A1, I3), B = kron(B1, I3): the state is stacked by
derivative order, ``x = [p (3), v (3)]`` or ``[p (3), v (3), a (3)]``, and the
input is ``u (3)``. (The paper writes "forward Euler" but its B_i is the exact
zero-order-hold one; we take the exact discretisation, which its matrices give.)

Stacking k = 1..K, with x[k] = A^k x0 + sum_{m<k} A^{k-1-m} B u[m]:

    P = A0_p x0 + Lambda_p U,   V = A0_v x0 + Lambda_v U,

with P = [p[1]; ...; p[K]] (3K,) and U = [u[0]; ...; u[K-1]] (3K,).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "PredictionMatrices",
    "discrete_model",
    "fine_position_matrices",
    "prediction_matrices",
    "rollout",
    "stacked_state_matrices",
]


def discrete_model(model: str, step_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Exact ZOH discretisation (A (n, n), B (n, 3)) of the 3-D integrator chain.

    Args:
        model: ``"double"`` (n = 6) or ``"triple"`` (n = 9).
        step_s: sampling step h in [s].
    """
    h = float(step_s)
    if model == "double":
        A1 = np.array([[1.0, h], [0.0, 1.0]])
        B1 = np.array([[h**2 / 2.0], [h]])
    elif model == "triple":
        A1 = np.array([[1.0, h, h**2 / 2.0], [0.0, 1.0, h], [0.0, 0.0, 1.0]])
        B1 = np.array([[h**3 / 6.0], [h**2 / 2.0], [h]])
    else:
        raise ValueError(f"model={model!r}: one of double, triple")
    eye3 = np.eye(3)
    return np.kron(A1, eye3), np.kron(B1, eye3)


@dataclass(frozen=True)
class PredictionMatrices:
    """Stacked prediction matrices over a K-step horizon (on-demand DMPC Eq. 10).

    Attributes:
        A0_pos: (3K, n) free response of p[1..K] to x0.
        Lambda_pos: (3K, 3K) block lower-triangular response of p[1..K] to U.
        A0_vel: (3K, n) free response of v[1..K].
        Lambda_vel: (3K, 3K) response of v[1..K] to U.
        A0_acc: (3K, n) free response of the constrained accelerations.
        Lambda_acc: (3K, 3K) response of the constrained accelerations. For the
            double integrator the acceleration on [t_k, t_k+1) is the input u[k]
            (k = 0..K-1): A0_acc = 0, Lambda_acc = I. For the triple integrator
            it is the state a[k], k = 1..K.
        A: (n, n) one-step state matrix; B: (n, 3) one-step input matrix.
    """

    A0_pos: np.ndarray
    Lambda_pos: np.ndarray
    A0_vel: np.ndarray
    Lambda_vel: np.ndarray
    A0_acc: np.ndarray
    Lambda_acc: np.ndarray
    A: np.ndarray
    B: np.ndarray

    @property
    def horizon_steps(self) -> int:
        """K."""
        return self.Lambda_pos.shape[1] // 3

    def state_matrices(self) -> tuple[np.ndarray, np.ndarray]:
        """(A0_x (K n, n), Lambda_x (K n, 3K)) of the full stacked states x[1..K]."""
        return stacked_state_matrices(self.A, self.B, self.horizon_steps)


def stacked_state_matrices(A: np.ndarray, B: np.ndarray, horizon_steps: int) -> tuple[np.ndarray, np.ndarray]:
    """(A0_x (K n, n), Lambda_x (K n, 3K)) with x[k] = A^k x0 + sum_{m<k} A^(k-1-m) B u[m].

    Args:
        A: (n, n) one-step state matrix.
        B: (n, 3) one-step input matrix.
        horizon_steps: K.
    """
    n, K = A.shape[0], int(horizon_steps)
    powers = [np.eye(n)]
    for _ in range(K):
        powers.append(A @ powers[-1])
    A0_x = np.zeros((K * n, n))
    Lambda_x = np.zeros((K * n, B.shape[1] * K))
    m_in = B.shape[1]
    for k in range(1, K + 1):
        A0_x[(k - 1) * n : k * n] = powers[k]  # x[k] = A^k x0 + ...
        for m in range(k):
            Lambda_x[(k - 1) * n : k * n, m_in * m : m_in * (m + 1)] = powers[k - 1 - m] @ B  # A^(k-1-m) B u[m]
    return A0_x, Lambda_x


def prediction_matrices(model: str, step_s: float, horizon_steps: int) -> PredictionMatrices:
    """Build P = A0_pos x0 + Lambda_pos U and the velocity/acceleration analogues.

    Args:
        model: ``"double"`` or ``"triple"``.
        step_s: h in [s].
        horizon_steps: K.
    """
    A, B = discrete_model(model, step_s)
    n, K = A.shape[0], int(horizon_steps)
    A0_x, Lambda_x = stacked_state_matrices(A, B, K)
    rows = np.arange(K)[:, None] * n

    def select(offset: int) -> np.ndarray:
        return (rows + offset + np.arange(3)[None, :]).ravel()

    pos_rows, vel_rows = select(0), select(3)
    if model == "double":
        A0_acc, Lambda_acc = np.zeros((3 * K, n)), np.eye(3 * K)  # a on [t_k, t_k+1) = u[k]
    else:
        acc_rows = select(6)
        A0_acc, Lambda_acc = A0_x[acc_rows], Lambda_x[acc_rows]  # a[k], k = 1..K
    return PredictionMatrices(
        A0_pos=A0_x[pos_rows],
        Lambda_pos=Lambda_x[pos_rows],
        A0_vel=A0_x[vel_rows],
        Lambda_vel=Lambda_x[vel_rows],
        A0_acc=A0_acc,
        Lambda_acc=Lambda_acc,
        A=A,
        B=B,
    )


def fine_position_matrices(
    model: str, step_s: float, horizon_steps: int, substeps: int
) -> tuple[np.ndarray, np.ndarray]:
    """Positions at S = ``substeps`` times per step: p(t_now + j h / S), j = 1..K S.

    Inside step k (from t_k to t_k+1) the position at t_k + tau is, exactly
    under the zero-order hold, C [A(tau) x[k] + B(tau) u[k]] with A(tau), B(tau)
    the one-step matrices for step tau; x[k] is itself affine in x0 and U, so

        p_fine = A0_fine x0 + Lambda_fine U.

    With S = 1 this is (A0_pos, Lambda_pos).

    Returns:
        A0_fine (3 K S, n) and Lambda_fine (3 K S, 3K).
    """
    K, S = int(horizon_steps), int(substeps)
    A, B = discrete_model(model, step_s)
    n = A.shape[0]
    A0_x, Lambda_x = stacked_state_matrices(A, B, K)
    A0_x = np.vstack([np.eye(n), A0_x])  # x[0..K]
    Lambda_x = np.vstack([np.zeros((n, 3 * K)), Lambda_x])
    A0_fine = np.zeros((3 * K * S, n))
    Lambda_fine = np.zeros((3 * K * S, 3 * K))
    for s in range(1, S + 1):
        A_tau, B_tau = discrete_model(model, step_s * s / S)
        CA, CB = A_tau[:3], B_tau[:3]
        for k in range(K):
            j = k * S + (s - 1)  # fine index of t_k + s h / S
            rows = slice(3 * j, 3 * j + 3)
            # p(t_k + tau) = C A(tau) x[k] + C B(tau) u[k]
            A0_fine[rows] = CA @ A0_x[k * n : (k + 1) * n]
            Lambda_fine[rows] = CA @ Lambda_x[k * n : (k + 1) * n]
            Lambda_fine[rows, 3 * k : 3 * k + 3] += CB
    return A0_fine, Lambda_fine


def rollout(model: str, step_s: float, x0: np.ndarray, inputs: np.ndarray) -> np.ndarray:
    """Step-by-step simulation x[k+1] = A x[k] + B u[k]; returns states (K+1, n).

    Args:
        model: ``"double"`` or ``"triple"``.
        step_s: h in [s].
        x0: (n,) initial state ``[p, v]`` or ``[p, v, a]``.
        inputs: (K, 3) inputs u[0..K-1] (acceleration or jerk).
    """
    A, B = discrete_model(model, step_s)
    inputs = np.asarray(inputs, float).reshape(-1, 3)
    states = np.empty((inputs.shape[0] + 1, A.shape[0]))
    states[0] = np.asarray(x0, float)
    for k, u in enumerate(inputs):
        states[k + 1] = A @ states[k] + B @ u  # x[k+1] = A x[k] + B u[k]
    return states
