"""MP-CDE trajectory optimiser: MINCO over inner points and times, solved with L-BFGS.

MP-CDE Sec. IV-C, Eq. 15 (GCOPTER's unconstrained reformulation):

    min_{q, tau}  w_e J(c, T) + w_t sum_i T_i + F_vel + F_acc + F_obstacle + F_swarm,
    c = M(q, T),  T_i = sigma(tau_i),

with ``J`` the jerk energy of :mod:`planners.minco`, the penalties ``F`` of
:mod:`planners.trajectory_cost` (the swarm term is Eq. 16) and
``sigma(tau) = tau^2/2 + tau + 1`` for ``tau > 0``, ``1 / (tau^2/2 - tau + 1)``
otherwise (GCOPTER's C^1 map of R onto T > 0). Build, then solve:
``problem = build_trajectory_problem(...)``, ``result = solve(problem)``.

Solver: our own L-BFGS (:mod:`planners.lbfgs`: memory 16, two-loop recursion, Lewis-Overton weak-Wolfe
line search as in GCOPTER's ``lbfgs.hpp``); ``solver="scipy"`` runs
``scipy.optimize.minimize(method="L-BFGS-B")`` on the same cost instead.
``benchmarks/bench_minco.py`` measures both. With an ``OccupancySnapshot`` (or no
field) the whole L-BFGS runs compiled; any other ``DistanceField`` is called from
a Python driver of the same algorithm. Numba's on-disk cache does not see edits
to compiled callees in other modules (minco, trajectory_cost): after editing their
kernels, delete ``planners/__pycache__/trajectory_optimizer.*.nb[ic]``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, fields

import numpy as np
from numba import njit
from scipy.optimize import minimize

from perception.types import DistanceField, NeighborPrediction, trilinear_compiled
from planners.lbfgs import lbfgs_loop, lbfgs_result, lbfgs_start, lbfgs_tell
from planners.minco import MincoTrajectory
from planners.trajectory_cost import PenaltyParameters, TrajectoryCost
from planners.trajectory_variables import _backward, _forward, _tau_to_time, _time_to_tau
from sim.checks import ConfigError

__all__ = [
    "TrajectoryOptimizationError",
    "TrajectoryOptimizerConfig",
    "TrajectoryOptimizerResult",
    "TrajectoryProblem",
    "build_trajectory_problem",
    "solve",
]


@dataclass(frozen=True)
class TrajectoryOptimizerConfig(PenaltyParameters):
    """Settings of the MINCO optimiser (MP-CDE Eq. 15-16).

    The limits, clearances, penalty weights and K are the fields of
    :class:`planners.trajectory_cost.PenaltyParameters` (documented there, same defaults):
    limits (2.0 m/s, 4.0 m/s^2), obstacle_clearance_m (0.4 m),
    swarm_clearance_m (C_s, 0.7 m, MP-CDE Table I), swarm_z_scale (c, 2.0), clearance_margin_m (0.1 m),
    uncertainty_sigma (1.0), max_uncertainty_inflation_m (0.5 m), swarm_recovery_mps (inf: off;
    measured: docs/results/minco.md#swarm_recovery_mps-on-radio_outage-seeds-0-5), weight_vel, weight_acc, weight_obstacle, weight_swarm (w_s)
    (1e5 each), samples_per_piece (K, 16). The optimiser adds:

    Attributes:
        weight_energy: w_e on the jerk energy [s^5/m^2 (cost per unit energy)]; default 1.
        weight_time: w_t on the total duration [1/s]; default 20 (aggressiveness).
        max_piece_length_m: front-end segments longer than this are split evenly [m]; default 3.0.
        min_pieces: fewer pieces than this are made by splitting the longest segment [-]; default 3.
        initial_speed_fraction: initial durations are segment length / (fraction v_max) [-]; default 0.5.
        max_iterations: L-BFGS iteration limit [-]; default 200.
        gradient_tolerance: stop when ||g||_inf <= tol max(1, ||x||_inf) [-]; default 1e-5.
        relative_cost_tolerance: stop when the cost fell by less than this fraction over 3 iterations [-]; default 1e-4.
        lbfgs_memory: number of correction pairs [-]; default 16.
        solver: ``"lbfgs"`` (ours) or ``"scipy"`` (L-BFGS-B); default ``"lbfgs"``.
    """

    weight_energy: float = 1.0
    weight_time: float = 20.0
    max_piece_length_m: float = 3.0
    min_pieces: int = 3
    initial_speed_fraction: float = 0.5
    max_iterations: int = 200
    gradient_tolerance: float = 1e-5
    relative_cost_tolerance: float = 1e-4
    lbfgs_memory: int = 16
    solver: str = "lbfgs"

    def __post_init__(self) -> None:
        for name in ("weight_energy", "weight_time"):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(name, getattr(self, name), "must be >= 0")
        for name in ("max_piece_length_m", "gradient_tolerance"):
            if not getattr(self, name) > 0.0:
                raise ConfigError(name, getattr(self, name), "must be > 0")
        if not 0.0 < self.initial_speed_fraction <= 1.0:
            raise ConfigError("initial_speed_fraction", self.initial_speed_fraction, "must be in (0, 1]")
        if not self.relative_cost_tolerance >= 0.0:
            raise ConfigError("relative_cost_tolerance", self.relative_cost_tolerance, "must be >= 0")
        for name in ("max_iterations", "lbfgs_memory", "min_pieces"):
            if not (isinstance(getattr(self, name), int) and getattr(self, name) >= 1):
                raise ConfigError(name, getattr(self, name), "must be an int >= 1")
        if self.solver not in ("lbfgs", "scipy"):
            raise ConfigError("solver", self.solver, "must be 'lbfgs' or 'scipy'")
        super().__post_init__()  # the penalty fields (ValueError, one line)

    def penalty_parameters(self) -> PenaltyParameters:
        """The penalty part of this config, as a plain :class:`PenaltyParameters`."""
        return PenaltyParameters(**{f.name: getattr(self, f.name) for f in fields(PenaltyParameters)})


class TrajectoryProblem:
    """One planning problem: boundary states, initial points and times, field, neighbours, config.

    Attributes:
        start_pva, goal_pva: (3, 3) position [m], velocity [m/s], acceleration [m/s^2] rows.
        initial_points: (M-1, 3) initial inner points [m]; initial_durations: (M,) [s].
        t0_s: absolute start time [s]; config: the settings; cost: the penalties.
    """

    def __init__(
        self,
        start_pva: np.ndarray,
        goal_pva: np.ndarray,
        initial_points: np.ndarray,
        initial_durations: np.ndarray,
        distance_field: DistanceField | None,
        neighbors: list[NeighborPrediction],
        t0_s: float,
        config: TrajectoryOptimizerConfig,
    ):
        self.start_pva, self.goal_pva = start_pva, goal_pva
        self.initial_points, self.initial_durations = initial_points, initial_durations
        self.t0_s, self.config = float(t0_s), config
        self.distance_field, self.neighbors = distance_field, list(neighbors)
        self.cost = TrajectoryCost(config.penalty_parameters(), t0_s, distance_field, self.neighbors, start_pva[0])
        self.num_pieces = int(initial_durations.shape[0])
        self.x0 = np.concatenate([initial_points.ravel(), _time_to_tau(initial_durations)])
        self.evaluations = 0
        self.last_terms = np.zeros(9)  # penalty terms, statistics (TrajectoryCost.accumulate), energy
        self.last_coefficients = np.zeros((6 * self.num_pieces, 3))
        self.last_durations = initial_durations.copy()
        self._no_dist, self._no_grad = np.zeros(0), np.zeros((0, 3))

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Inner points (M-1, 3) [m] and durations (M,) [s] from the decision vector x (3(M-1) + M,)."""
        n_q = 3 * (self.num_pieces - 1)
        return x[:n_q].reshape(-1, 3).copy(), _tau_to_time(np.ascontiguousarray(x[n_q:], dtype=float))

    def cost_and_gradient(self, x: np.ndarray, stats: bool = False) -> tuple[float, np.ndarray]:
        """Total cost (MP-CDE Eq. 15) and its gradient (3(M-1) + M,) by x (3(M-1) + M,).

        ``last_terms`` then holds the penalty terms and sample statistics; the minimum
        swarm margin (``last_terms[7]``) only when ``stats`` is True.
        """
        cfg, cost, nb = self.config, self.cost, self.cost.neighbors
        K, n_q = cost.params.samples_per_piece, 3 * (self.num_pieces - 1)
        x = np.ascontiguousarray(x, dtype=float)
        T, coeffs, ab, pts = _forward(self.start_pva, self.goal_pva, x, n_q, K)
        if self.distance_field is not None:
            d, gd = cost.distance_and_gradient(pts)
            use_field = True
        else:
            d, gd, use_field = self._no_dist, self._no_grad, False
        f, g = _backward(
            x, n_q, T, coeffs, ab, K, cost.t0_s, cost.parameter_vector, d, gd, use_field,
            nb.times_s, nb.pos_world, nb.vel_world, nb.offsets, nb.t_last_s, nb.radius_terms,
            cfg.weight_energy, cfg.weight_time, self.last_terms, stats,
        )  # fmt: skip
        self.evaluations += 1
        self.last_coefficients, self.last_durations = coeffs, T
        return f, g


class TrajectoryOptimizationError(RuntimeError):
    """The optimiser failed (non-finite cost or no descent possible); ``problem`` is the failing problem."""

    def __init__(self, reason: str, problem: TrajectoryProblem):
        super().__init__(reason)
        self.reason, self.problem = reason, problem


@dataclass(frozen=True)
class TrajectoryOptimizerResult:
    """Outcome of :func:`solve`.

    Attributes:
        trajectory: the optimised trajectory (``t0_s`` = the problem's start time).
        status: ``"converged"`` (gradient or cost tolerance met), ``"max_iterations"``,
            or ``"line_search_stalled"`` (no further decrease found; best point kept).
        cost: total cost; energy_cost, time_cost, vel_cost, acc_cost, obstacle_cost,
            swarm_cost: its weighted terms.
        iterations: solver iterations; evaluations: cost evaluations.
        solve_time_s: wall time of :func:`solve` [s].
        max_speed_mps, max_acc_mps2, min_obstacle_distance_m, min_swarm_margin_m:
            sampled statistics of the result (``min_swarm_margin_m`` is the
            smallest ``||E^{1/2}(p - p_n)|| - r_n``).
        feasible: every sampled limit and clearance holds (1 % slack on the limits).
    """

    trajectory: MincoTrajectory
    status: str
    cost: float
    energy_cost: float
    time_cost: float
    vel_cost: float
    acc_cost: float
    obstacle_cost: float
    swarm_cost: float
    iterations: int
    evaluations: int
    solve_time_s: float
    max_speed_mps: float
    max_acc_mps2: float
    min_obstacle_distance_m: float
    min_swarm_margin_m: float
    feasible: bool


def build_trajectory_problem(
    start_pva: np.ndarray,
    goal_pva: np.ndarray,
    waypoints_world: np.ndarray,
    distance_field: DistanceField | None,
    neighbors: list[NeighborPrediction],
    t0_s: float,
    config: TrajectoryOptimizerConfig = TrajectoryOptimizerConfig(),
) -> TrajectoryProblem:
    """Build the problem from a front-end path.

    Args:
        start_pva, goal_pva: (3, 3) rows position [m], velocity [m/s], acceleration [m/s^2].
        waypoints_world: (n, 3) front-end path [m] with start and goal included, n >= 2
            (``PathSearchResult.waypoints_world``); its first and last rows are
            replaced by the start and goal positions, segments longer than
            ``max_piece_length_m`` are split evenly, and the inner points become q.
        distance_field: obstacle field or None; neighbors: predictions of the other drones.
        t0_s: absolute time [s] of the start state.
    """
    start, goal = (np.ascontiguousarray(a, dtype=float) for a in (start_pva, goal_pva))
    if start.shape != (3, 3) or goal.shape != (3, 3) or not (np.all(np.isfinite(start)) and np.all(np.isfinite(goal))):
        raise ValueError(f"start_pva/goal_pva shapes={start.shape}/{goal.shape}: must be finite (3, 3)")
    wp = np.array(waypoints_world, dtype=float)
    if wp.ndim != 2 or wp.shape[0] < 2 or wp.shape[1] != 3 or not np.all(np.isfinite(wp)):
        raise ValueError(f"waypoints_world shape={wp.shape}: must be finite (n, 3), n >= 2")
    wp[0], wp[-1] = start[0], goal[0]
    n_split = np.maximum(1, np.ceil(np.linalg.norm(np.diff(wp, axis=0), axis=1) / config.max_piece_length_m))
    while n_split.sum() < config.min_pieces:  # too few pieces to move in space: split the longest further
        n_split[np.argmax(np.linalg.norm(np.diff(wp, axis=0), axis=1) / n_split)] += 1
    points = [wp[0]]
    for a, b, n in zip(wp[:-1], wp[1:], n_split.astype(int)):
        points.extend(a + (b - a) * (k / n) for k in range(1, n + 1))
    points = np.array(points)
    lengths = np.linalg.norm(np.diff(points, axis=0), axis=1)
    durations = np.maximum(lengths / (config.initial_speed_fraction * config.limits.v_max_mps), 0.2)
    return TrajectoryProblem(start, goal, points[1:-1].copy(), durations, distance_field, neighbors, t0_s, config)


@njit(cache=True)
def _lbfgs_compiled(args, x0, mem, max_iterations, g_tol, rel_tol):
    """:func:`planners.lbfgs.lbfgs_loop` with :func:`_compiled_cost`, compiled end to end."""
    st = lbfgs_start(x0, mem, max_iterations, g_tol, rel_tol)
    while lbfgs_tell(st, *_compiled_cost(st.trial, args)):
        pass
    return lbfgs_result(st)


@njit(cache=True)
def _compiled_cost(x, args):
    """Eq. 15 cost and gradient with everything compiled (OccupancySnapshot field or none)."""
    head, tail, n_q, K, t0, prm, grid, grid_origin, voxel_m, use_field, nb, w_e, w_t, out = args
    T, coeffs, ab, pts = _forward(head, tail, x, n_q, K)
    if use_field:
        d, gd = trilinear_compiled(grid, grid_origin, voxel_m, pts)
    else:
        d, gd = np.zeros(0), np.zeros((0, 3))
    nb_t, nb_p, nb_v, nb_off, nb_tl, nb_cov = nb
    return _backward(
        x, n_q, T, coeffs, ab, K, t0, prm, d, gd, use_field,
        nb_t, nb_p, nb_v, nb_off, nb_tl, nb_cov, w_e, w_t, out, False,
    )  # fmt: skip


_STATUS = ("converged", "max_iterations", "line_search_stalled")


def _lbfgs(problem: TrajectoryProblem) -> tuple[np.ndarray, float, int, str]:
    """Our L-BFGS: compiled end to end for an OccupancySnapshot or no field, Python loop otherwise."""
    cfg = problem.config
    cost = problem.cost
    opts = (cfg.lbfgs_memory, cfg.max_iterations, cfg.gradient_tolerance, cfg.relative_cost_tolerance)
    if problem.distance_field is None or cost.grid is not None:
        nb = cost.neighbors
        grid = cost.grid if cost.grid is not None else (np.zeros((2, 2, 2)), np.zeros(3), 1.0)
        args = (
            problem.start_pva, problem.goal_pva, 3 * (problem.num_pieces - 1), cost.params.samples_per_piece,
            cost.t0_s, cost.parameter_vector, grid[0], grid[1], grid[2], cost.grid is not None,
            (nb.times_s, nb.pos_world, nb.vel_world, nb.offsets, nb.t_last_s, nb.radius_terms),
            float(cfg.weight_energy), float(cfg.weight_time), np.zeros(9),
        )  # fmt: skip
        x, f, k, code, evals = _lbfgs_compiled(args, problem.x0, *opts)
        problem.evaluations += int(evals)
    else:
        x, f, k, code, _ = lbfgs_loop(lambda x_, p: p.cost_and_gradient(x_), problem, problem.x0, *opts)
    if code == 3:
        raise TrajectoryOptimizationError(f"non-finite initial cost {f!r}", problem)
    return x, float(f), int(k), _STATUS[code]


def _scipy(problem: TrajectoryProblem) -> tuple[np.ndarray, float, int, str]:
    cfg = problem.config
    res = minimize(
        problem.cost_and_gradient,
        problem.x0,
        jac=True,
        method="L-BFGS-B",
        options={
            "maxiter": cfg.max_iterations,
            "maxcor": cfg.lbfgs_memory,
            "gtol": cfg.gradient_tolerance,
            "ftol": cfg.relative_cost_tolerance,
        },
    )
    if not np.isfinite(res.fun):
        raise TrajectoryOptimizationError(f"non-finite cost {res.fun!r}: {res.message}", problem)
    code = 0 if res.success else 1 if res.nit >= cfg.max_iterations else 2
    return res.x, float(res.fun), int(res.nit), _STATUS[code]


def solve(problem: TrajectoryProblem) -> TrajectoryOptimizerResult:
    """Minimise MP-CDE Eq. 15 over inner points and times; raises :class:`TrajectoryOptimizationError`."""
    t_start = time.perf_counter()
    problem.evaluations = 0
    cfg = problem.config
    x, _, iterations, status = _lbfgs(problem) if cfg.solver == "lbfgs" else _scipy(problem)
    f, _ = problem.cost_and_gradient(x, stats=True)  # leaves coefficients, terms and statistics at x
    if not np.isfinite(f):
        raise TrajectoryOptimizationError(f"non-finite final cost {f!r}", problem)
    terms = problem.last_terms
    T = problem.last_durations
    feasible = bool(
        terms[4] <= 1.01 * cfg.limits.v_max_mps
        and terms[5] <= 1.01 * cfg.limits.a_max_mps2
        and terms[6] >= cfg.obstacle_clearance_m
        and terms[7] >= cfg.swarm_clearance_m
    )
    return TrajectoryOptimizerResult(
        trajectory=MincoTrajectory(problem.last_coefficients.copy(), T.copy(), problem.t0_s),
        status=status,
        cost=float(f),
        energy_cost=cfg.weight_energy * float(terms[8]),
        time_cost=cfg.weight_time * float(np.sum(T)),
        vel_cost=float(terms[0]),
        acc_cost=float(terms[1]),
        obstacle_cost=float(terms[2]),
        swarm_cost=float(terms[3]),
        iterations=int(iterations),
        evaluations=int(problem.evaluations),
        solve_time_s=time.perf_counter() - t_start,
        max_speed_mps=float(terms[4]),
        max_acc_mps2=float(terms[5]),
        min_obstacle_distance_m=float(terms[6]),
        min_swarm_margin_m=float(terms[7]),
        feasible=feasible,
    )
