"""Drone i's ADMM subproblem (Stomberg et al. Eq. 4a, Algorithm 2 Step 3), set up in OSQP once.

With the drone's share f_i(z_i) = 1/2 z_i' H_i z_i + g_i' z_i + c_i of the OCP and
its constraints Z_i (:mod:`planners.dmpc.admm.ocp`, which also lays out z_i)
and the ADMM penalty rho:

    z_i^{l+1} = argmin_{z in Z_i} f_i(z) + gamma_i' (z - zbar_i) + rho/2 ||z - zbar_i||^2
              = argmin_{z in Z_i} 1/2 z' (H_i + rho I) z + (g_i + gamma_i - rho zbar_i)' z.

H_i holds, besides the own tracking, input and slack terms, half of each
edge's formation term against the copy (see the edge split in
:mod:`planners.dmpc.admm.ocp`): (w_f/2) ||p - w_ji - d_ij||^2, Hessian
w_f [I, -I; -I, I] on (p_i, w_ji).

**No refactorisation.** OSQP's P = H_i + rho I and A = A_i are set up ONCE per
drone (:class:`LocalAdmmQp`); an ADMM iteration changes only q, an MPC step
only q and the bounds of the first dynamics rows (x0) and, with Remark 1, of
the u[0] rows (u(t)). OSQP refactorises its KKT matrix on a matrix update, on
a change of its step size rho, and on a bounds update that changes a row's
type (equality / inequality / free: its rho vector depends on the type). No
row here ever changes type (the u[0] rows are equalities in every step with
Remark 1, inequalities in every step without; the free k = 1 soft rows stay
free), and OSQP's adaptive step size is off by default (``osqp_adaptive_rho``;
``rho_updates`` counts its refactorisations when on), so no call refactorises.
The unit tests hold this with a recording proxy around the solver object.

**dSQP** (Algorithm 3) adds the linearised minimum-distance rows of the pairs
the drone holds (:class:`planners.dmpc.admm.distance.DistanceRows`) below the
own rows. With the Gauss-Newton Hessian (Remark 4) and f_i quadratic, QP (6)
in the step Delta z is this same QP in z = z^q + Delta z (the cost
1/2 Dz' H Dz + grad f(z^q)' Dz is f_i(z^q + Dz) - f_i(z^q), the linear rows
are exact), so dSQP's local QP is the ADMM one with those rows:
:meth:`LocalAdmmQp.linearise` writes their values at the SQP iterate (one
OSQP matrix update, hence one refactorisation, per SQP iteration); an ADMM
iteration still changes only q.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import osqp
import scipy.sparse as sp

from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.admm.distance import DistanceRows
from planners.dmpc.admm.ocp import DroneLayout, own_bounds, own_constraint_matrix, own_cost
from planners.dmpc.sparse_qp.osqp_core import solver_core
from planners.dmpc.sparse_qp.pattern import SparsePattern

__all__ = ["AdmmLocalQpError", "LocalAdmmQp", "LocalSolve"]

# A local QP that hits osqp_max_iter is used as it is (the fixed-budget ADMM is inexact anyway) and counted.
_ACCEPTED = (
    osqp.SolverStatus.OSQP_SOLVED,
    osqp.SolverStatus.OSQP_SOLVED_INACCURATE,
    osqp.SolverStatus.OSQP_MAX_ITER_REACHED,
)
_MAX_ITER = osqp.SolverStatus.OSQP_MAX_ITER_REACHED


class AdmmLocalQpError(RuntimeError):
    """OSQP did not solve drone ``drone_id``'s local QP (Step 3); carries the QP's vectors.

    Attributes:
        drone_id: the drone.
        status: OSQP's status string.
        q: (n_i,) linear cost that failed.
        lower: (m_i,) lower bounds; upper: (m_i,) upper bounds.
    """

    def __init__(self, drone_id: int, status: str, q: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> None:
        super().__init__(f"drone {drone_id}: local ADMM QP not solved, OSQP status {status!r}")
        self.drone_id, self.status = drone_id, status
        self.q, self.lower, self.upper = q, lower, upper


@dataclass(frozen=True)
class LocalSolve:
    """One solve of the local QP (4a).

    Attributes:
        z: (n_i,) the minimiser z_i^{l+1}.
        iterations: OSQP iterations.
        rho_updates: OSQP adaptive-step refactorisations during this solve.
        status: OSQP status string.
        hit_max_iter: OSQP stopped at ``osqp_max_iter`` (z is its last iterate).
    """

    z: np.ndarray
    iterations: int
    rho_updates: int
    status: str
    hit_max_iter: bool


class LocalAdmmQp:
    """Drone i's ADMM subproblem (4a), set up in OSQP once; see the module docstring.

    Args:
        config: the settings.
        drone_id: i (for error messages).
        neighbour_offsets: {j: d_ij (3,)} desired p_i - p_j [m] per neighbour.
        distance_partners: the neighbours whose minimum-distance rows this
            drone holds (dSQP; :func:`planners.dmpc.admm.distance.owned_partners`),
            () for ADMM without them.
    """

    def __init__(self, config: AdmmFormationConfig, drone_id: int, neighbour_offsets: dict[int, np.ndarray],
                 distance_partners: tuple[int, ...] = ()) -> None:  # fmt: skip
        self.config = config
        self.drone_id = int(drone_id)
        self.layout = DroneLayout(config.horizon_steps, tuple(sorted(neighbour_offsets)))
        lay, K = self.layout, config.horizon_steps
        self._offsets = {j: np.asarray(neighbour_offsets[j], float).reshape(3) for j in lay.neighbour_ids}
        n, n_own = lay.size, lay.own_size
        A_own = own_constraint_matrix(config).tocoo()
        self.distance = None
        if distance_partners:
            self.distance = DistanceRows(lay, tuple(distance_partners), config.d_min_m, config.downwash,
                                         first_step_free=config.delay_compensation,
                                         against_means=config.distance_rows == "means")  # fmt: skip
        pattern = SparsePattern()
        pattern.add(A_own.row, A_own.col, A_own.data)
        m_own = A_own.shape[0]
        rows = m_own
        if self.distance is not None:
            self._distance_slice = self.distance.add_to(pattern, m_own)
            rows += self.distance.count
        self.A, self._coo_to_csc = pattern.to_csc((rows, n))
        self._m_own = m_own
        self._distance_free = True  # until the first linearisation
        self._bounds_dirty = False  # bounds changed since they were last sent to OSQP
        H_own, _, _ = own_cost(config, np.zeros((K, 3)))
        # Half of each edge's formation term (module docstring): (w_f/2) ||p - w_j - d||^2
        # -> Hessian w_f [I, -I; -I, I] on (p, w_j).
        w_f = np.repeat(config.formation_weights(), 3)
        H = sp.lil_matrix((n, n))
        H[:n_own, :n_own] = H_own
        for j in lay.neighbour_ids:
            p, w = np.arange(lay.pos.start, lay.pos.stop), np.arange(lay.copy(j).start, lay.copy(j).stop)
            H[p, p] += w_f
            H[w, w] += w_f
            H[p, w] += -w_f
            H[w, p] += -w_f
        self.H = sp.csc_matrix(H)  # H_i of f_i
        self.P = sp.triu(self.H + config.rho * sp.eye(n), format="csc")  # H_i + rho I  (4a)
        self.g = np.zeros(n)
        self.cost_constant = 0.0
        self.lower, self.upper = self._with_distance_bounds(
            *own_bounds(config, np.zeros(6), np.zeros(3) if config.delay_compensation else None)
        )
        self._q = np.zeros(n)
        solver = osqp.OSQP()
        solver.setup(
            self.P, self._q, self.A, self.lower, self.upper,
            verbose=False, eps_abs=config.osqp_eps_abs, eps_rel=config.osqp_eps_rel,
            max_iter=config.osqp_max_iter, polishing=False, warm_starting=True,
            adaptive_rho=config.osqp_adaptive_rho, rho=config.osqp_rho, check_termination=5,
        )  # fmt: skip; residuals checked every 5 OSQP iterations: a warm-started local QP takes about 5
        # The compiled solver object (osqp 1.x) is called directly, as in planners.dmpc.qp: the Python
        # wrapper's per-call bookkeeping costs more than a warm-started solve of this size.
        self._core = solver_core(solver)
        self._osqp = solver

    # ---------------------------------------------------------------- per MPC step
    def set_step(
        self, state_world: np.ndarray, reference_world: np.ndarray, input_now_world: np.ndarray | None
    ) -> None:
        """New MPC step: bounds from x0 (and u(t)), g_i and c_i from the reference.

        Args:
            state_world: (6,) [p0 m, v0 m/s].
            reference_world: (K, 3) r_i[1..K] [m].
            input_now_world: (3,) u(t) [m/s^2] fixing u[0] (Remark 1), or None.
        """
        cfg, lay = self.config, self.layout
        self.lower, self.upper = self._with_distance_bounds(*own_bounds(cfg, state_world, input_now_world))
        _, g_own, c_own = own_cost(cfg, reference_world)
        g = np.zeros(lay.size)
        g[: lay.own_size] = g_own
        w_f = np.repeat(cfg.formation_weights(), 3)
        c = c_own
        for j, d in self._offsets.items():
            d_k = np.tile(d, cfg.horizon_steps)
            g[lay.pos] -= w_f * d_k  # (w_f/2) ||p - w - d||^2: linear part -w_f d' p + w_f d' w
            g[lay.copy(j)] += w_f * d_k
            c += 0.5 * float(np.sum(w_f * d_k**2))
        self.g, self.cost_constant = g, c

    def _with_distance_bounds(self, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.distance is None:
            return lower, upper
        d_lo, d_hi = self.distance.bounds(free=self._distance_free)
        return np.r_[lower, d_lo], np.r_[upper, d_hi]

    def linearise(self, zbar: np.ndarray, free: bool = False, fallback_world: np.ndarray | None = None) -> None:
        """dSQP Algorithm 3 Step 3: the distance rows linearised at the iterate ``zbar`` (n_i,).

        Sends the new matrix values to OSQP now (one refactorisation) and the
        rows' bounds with the next solve; ``free`` leaves every distance row
        unbounded (a cold step's first SQP iteration, whose copies are
        guesses). ``fallback_world`` (3,): direction for coinciding plans.
        """
        if self.distance is None:
            raise RuntimeError(f"drone {self.drone_id}: no distance rows (ADMM without dSQP)")
        data = self.A.data
        data[self._coo_to_csc[self._distance_slice]] = self.distance.values(zbar, fallback_world)
        self._core.update_data_mat(P_x=None, P_i=None, A_x=data, A_i=None)
        if bool(free) != self._distance_free or self.distance.against_means:  # the means move the bounds too
            self._distance_free = bool(free)
            self.lower[self._m_own :], self.upper[self._m_own :] = self.distance.bounds(free=self._distance_free)
            self._bounds_dirty = True

    def warm_start(self, x: np.ndarray, y: np.ndarray) -> None:
        """Start OSQP's next solve from primal ``x`` (n_i,) and dual ``y`` (m_i,)."""
        self._core.warm_start(x, y)

    # ---------------------------------------------------------------- per ADMM iteration
    def solve(self, gamma: np.ndarray, zbar: np.ndarray, update_bounds: bool) -> tuple[LocalSolve, np.ndarray]:
        """Eq. (4a): argmin over Z_i of f_i(z) + gamma'(z - zbar) + rho/2 ||z - zbar||^2.

        Args:
            gamma: (n_i,) multipliers gamma_i^l.
            zbar: (n_i,) zbar_i^l.
            update_bounds: also send the bounds of :meth:`set_step` (first
                iteration of an MPC step); otherwise only q changes.

        Returns:
            the :class:`LocalSolve` and OSQP's dual solution y (m_i,).

        Raises:
            AdmmLocalQpError: OSQP returned no solution (infeasible, non-convex...;
                reaching ``osqp_max_iter`` is not an error, see :class:`LocalSolve`).
        """
        q = self._q
        np.subtract(self.g + gamma, self.config.rho * zbar, out=q)  # q = g_i + gamma - rho zbar  (4a)
        core = self._core
        if update_bounds or self._bounds_dirty:
            core.update_data_vec(q=q, l=self.lower, u=self.upper)
            self._bounds_dirty = False
        else:
            core.update_data_vec(q=q, l=None, u=None)
        core.solve()
        info = core.info
        if info.status_val not in _ACCEPTED:
            raise AdmmLocalQpError(self.drone_id, str(info.status), q.copy(), self.lower.copy(), self.upper.copy())
        sol = core.solution
        hit = info.status_val == _MAX_ITER
        return LocalSolve(sol.x, int(info.iter), int(info.rho_updates), str(info.status), hit), sol.y

    def objective(self, z: np.ndarray) -> float:
        """f_i(z) (n_i,) = 1/2 z' H_i z + g_i' z + c_i, the drone's share of the cost (1a)."""
        return float(0.5 * z @ (self.H @ z) + self.g @ z + self.cost_constant)
