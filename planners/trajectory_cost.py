"""Penalties sampled along a MINCO trajectory, with gradients by coefficients and times.

GCOPTER-style time integral of soft-constraint penalties (MP-CDE Eq. 15, the
``w_f f_f + w_s f_s`` terms): every piece i is sampled at ``K + 1`` points
``t_ij = j T_i / K`` and the penalty integral is the trapezoidal sum

    F = sum_i sum_j omega_j (T_i / K) P(p_i(t_ij), v_i(t_ij), a_i(t_ij), t0 + sum_{k<i} T_k + t_ij),

``omega_j = 1/2`` at the ends of a piece, 1 elsewhere. Every violation ``v``
enters as the C^2 cubic ``max(v, 0)^3`` (GCOPTER's choice):

* speed:      ``v = ||p'||^2 - v_max^2``
* acceleration: ``v = ||p''||^2 - a_max^2``
* obstacle:   ``v = (C_o + margin) - d(p)`` with ``d`` from a ``DistanceField``
* altitude band (our addition, off by default): ``v = max(z - z_hi, z_lo - z)``,
  summed into the obstacle term (both keep the samples in the free workspace)
* swarm (MP-CDE Eq. 16): ``v = (C_s + margin + r_n(t))^2 - ||E^{1/2} (p(t) - p_n(t))||^2``
  against each neighbour prediction ``p_n`` evaluated at the same absolute time,
  ``E = diag(1, 1, 1/c)``. Eq. 16 is garbled in our copy of the paper; we read it
  as EGO-Swarm's form, summed over samples, cubed for smoothness, and integrated
  over time like the other penalties. ``r_n(t)`` inflates the clearance by the
  prediction's uncertainty: ``r_n = min(n_sigma sqrt(tr P_pos(t)), r_max)``, the
  same radius as ``NeighborPrediction.uncertainty_radius`` (0 for exact radio
  plans), capped so that an old track cannot block the whole space.
* swarm, a neighbour already inside its clearance at the start (our addition,
  not in MP-CDE): if the start position p(t0) is at ``d0 < C_s + margin + r_n(t0)``
  from ``p_n(t0)`` (metric E), the clearance of that neighbour starts at d0 and
  grows back at ``swarm_recovery_mps``: ``clr_n(t) = C_s + margin + r_n(t) - s_n(t)``
  with ``s_n(t) = max(0, s0_n - rho (t - t0))``, ``s0_n = C_s + margin + r_n(t0) - d0``.
  With the full clearance from the first sample, a start inside it asks for
  an instantaneous jump in separation: the swarm penalty then outweighs the
  obstacle penalty and the optimiser returns a plan through an obstacle (as
  when the ``auto`` agent hands a drone flying 0.4 m behind another, as DMPC
  allows, to MINCO's C_s = 0.7 m). Off by default (``swarm_recovery_mps = inf``):
  close to a neighbour the relaxed clearance is small, and a cubic penalty on
  ``clr^2 - d^2`` is then weak, and it does not lower collisions
  (docs/results/minco.md#swarm_recovery_mps-on-radio_outage-seeds-0-5).

The gradient by ``T_i`` collects the growth of the sample spacing, the motion of
the sample along the piece, and (swarm term only) the dependence of the
neighbour's position and radius on the absolute sample time, which moves with
every ``T_k``, ``k <= i``. The kernels are numba-compiled; the distance field is
called once per evaluation on all samples (an ``OccupancySnapshot`` is read
directly by a compiled copy of its trilinear interpolation, tested equal to it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from perception.types import DistanceField, NeighborPrediction, OccupancySnapshot, trilinear_compiled
from planners.limits import KinematicLimits, require_infinite_jerk
from planners.trajectory_penalty import _inflation, _neighbor_state, _penalty_kernel, _sample_positions
from sim.checks import ConfigError, require_instance

__all__ = ["NeighborTable", "PenaltyParameters", "PenaltyTerms", "TrajectoryCost"]


@dataclass(frozen=True)
class PenaltyParameters:
    """Limits, clearances and weights of the sampled penalties (module docstring).

    :class:`planners.trajectory_optimizer.TrajectoryOptimizerConfig` extends it with the
    optimiser's own settings; its ``penalty_parameters()`` gives this part alone.

    Attributes:
        limits: speed and acceleration limits of the norms ||v|| <= ``v_max_mps``
            [m/s], ||a|| <= ``a_max_mps2`` [m/s^2] (Eq. 15; default 2.0 and 4.0);
            MINCO's penalties bound no jerk, so ``j_max_mps3`` must be inf.
        obstacle_clearance_m: clearance C_o to obstacles on the distance field [m]; default 0.4.
        swarm_clearance_m: swarm clearance C_s [m]; default 0.7 (MP-CDE Table I).
        swarm_z_scale: c in E = diag(1, 1, 1/c), c >= 1 [-]; default 2.0 (not given in
            the paper; 2.0 asks for 1.41 C_s of vertical clearance).
        clearance_margin_m: added to both clearances inside the penalty [m], so that the
            soft constraint settles outside C_o and C_s; default 0.1.
        uncertainty_sigma: n_sigma of the neighbour uncertainty radius [-]; default 1.0.
        max_uncertainty_inflation_m: cap r_max on the inflation [m]; default 0.5.
        swarm_recovery_mps: rate rho at which the clearance of a neighbour that the start
            is already inside grows back to C_s + margin [m/s] (module docstring); default
            ``inf``: no relaxation (the full clearance from the first sample, MP-CDE's form).
        weight_vel, weight_acc, weight_obstacle, weight_swarm: penalty weights [-]
            (w_s is MP-CDE's swarm weight); default 1e5 each.
        samples_per_piece: K, sample intervals per piece [-]; default 16 (GCOPTER).
        altitude_band_m: (z_lo, z_hi) world altitudes [m] the samples are held between by the penalty
            ``w_z max(z - z_hi, z_lo - z, 0)^3``, added to the obstacle term (not in MP-CDE: it keeps a
            swarm in the layer its cameras' +-29 deg vertical view covers; docs/results/safety.md#candidates-that-did-not-remove-the-class);
            default (-inf, inf): off.
        weight_altitude: w_z [-]; default 1e5.
    """

    limits: KinematicLimits = KinematicLimits(2.0, 4.0)
    obstacle_clearance_m: float = 0.4
    swarm_clearance_m: float = 0.7
    swarm_z_scale: float = 2.0
    clearance_margin_m: float = 0.1
    uncertainty_sigma: float = 1.0
    max_uncertainty_inflation_m: float = 0.5
    swarm_recovery_mps: float = float("inf")
    weight_vel: float = 1.0e5
    weight_acc: float = 1.0e5
    weight_obstacle: float = 1.0e5
    weight_swarm: float = 1.0e5
    samples_per_piece: int = 16
    altitude_band_m: tuple[float, float] = (-float("inf"), float("inf"))
    weight_altitude: float = 1.0e5

    def __post_init__(self) -> None:
        lo, hi = self.altitude_band_m
        if not lo < hi or np.isnan(lo) or np.isnan(hi):
            raise ConfigError("altitude_band_m", self.altitude_band_m, "must be (z_lo, z_hi) with z_lo < z_hi")
        require_instance("limits", self.limits, KinematicLimits)
        require_infinite_jerk(self.limits, "MINCO's penalties bound speed and acceleration only (Eq. 15)")
        for name in ("swarm_clearance_m",):
            if not getattr(self, name) > 0.0:
                raise ConfigError(name, getattr(self, name), "must be > 0")
        for name in (
            "obstacle_clearance_m",
            "clearance_margin_m",
            "uncertainty_sigma",
            "max_uncertainty_inflation_m",
            "weight_vel",
            "weight_acc",
            "weight_obstacle",
            "weight_swarm",
            "weight_altitude",
        ):
            if not getattr(self, name) >= 0.0:
                raise ConfigError(name, getattr(self, name), "must be >= 0")
        if not self.swarm_recovery_mps > 0.0:  # inf allowed
            raise ConfigError("swarm_recovery_mps", self.swarm_recovery_mps, "must be > 0 (inf: no relaxation)")
        if not self.swarm_z_scale >= 1.0:
            raise ConfigError("swarm_z_scale", self.swarm_z_scale, "must be >= 1")
        if not (isinstance(self.samples_per_piece, int) and self.samples_per_piece >= 2):
            raise ConfigError("samples_per_piece", self.samples_per_piece, "must be an int >= 2")


class NeighborTable:
    """Neighbour predictions packed into flat arrays for the compiled kernels.

    Attributes:
        times_s: (sum K,) sample times [s] of all neighbours, concatenated.
        pos_world: (sum K, 3) positions [m]; vel_world: (sum K, 3) velocities [m/s].
        offsets: (N+1,) start of neighbour n's samples.
        t_last_s: (N,) last sample time [s] (covariance grows after it).
        radius_terms: (N, 4) ``(a, b, c, s0)``: ``tr P_pos(t) = a + b dt + c dt^2`` with
            dt = max(t - t_last, 0), and s0 [m] the start deficit of the clearance (0 until
            :meth:`set_start_deficits`; module docstring).
    """

    def __init__(self, neighbors: list[NeighborPrediction]):
        n = len(neighbors)
        self.times_s = np.concatenate([np.asarray(nb.times_s, float) for nb in neighbors] + [np.zeros(0)])
        self.pos_world = np.concatenate([np.asarray(nb.pos_world, float) for nb in neighbors] + [np.zeros((0, 3))])
        self.vel_world = np.concatenate([np.asarray(nb.vel_world, float) for nb in neighbors] + [np.zeros((0, 3))])
        self.offsets = np.zeros(n + 1, dtype=np.int64)
        self.offsets[1:] = np.cumsum([np.shape(nb.times_s)[0] for nb in neighbors]).astype(np.int64)
        self.t_last_s = np.array([float(nb.times_s[-1]) for nb in neighbors]) if n else np.zeros(0)
        self.radius_terms = np.zeros((n, 4))
        for k, nb in enumerate(neighbors):
            P = np.asarray(nb.cov_world, float)
            # tr P_pos(t) = tr Ppp + dt tr(Ppv + Ppv^T) + dt^2 tr Pvv   (perception.types, MP-CDE Eq. 12)
            self.radius_terms[k, :3] = (np.trace(P[:3, :3]), 2.0 * np.trace(P[:3, 3:]), np.trace(P[3:, 3:]))

    def set_start_deficits(self, start_world: np.ndarray, t0_s: float, params: PenaltyParameters) -> None:
        """Set s0_n = max(0, C_s + margin + r_n(t0) - ||E^{1/2}(start - p_n(t0))||) [m] for every neighbour.

        All zero when ``params.swarm_recovery_mps`` is inf (no relaxation).
        """
        self.radius_terms[:, 3] = 0.0
        if not np.isfinite(params.swarm_recovery_mps):
            return
        p0 = np.asarray(start_world, float).reshape(3)
        c_sw = params.swarm_clearance_m + params.clearance_margin_m
        for n in range(self.count):
            px, py, pz, _, _, _ = _neighbor_state(
                self.times_s, self.pos_world, self.vel_world, self.offsets[n], self.offsets[n + 1], float(t0_s)
            )
            d = p0 - (px, py, pz)
            ell = float(np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2 / params.swarm_z_scale))
            r, _ = _inflation(self.radius_terms[n], float(t0_s) - self.t_last_s[n],
                              params.uncertainty_sigma, params.max_uncertainty_inflation_m)  # fmt: skip
            self.radius_terms[n, 3] = max(0.0, c_sw + r - ell)

    @property
    def count(self) -> int:
        """Number of neighbours N."""
        return int(self.t_last_s.shape[0])


@dataclass(frozen=True)
class PenaltyTerms:
    """Weighted penalty values, their partial gradients and sample statistics.

    Attributes:
        vel, acc, obstacle, swarm: weighted penalty integrals [-] (obstacle includes the altitude band's).
        grad_by_coeffs: (6M, 3) partial gradient of their sum by the coefficients.
        grad_by_times: (M,) partial gradient of their sum by the durations.
        max_speed_mps, max_acc_mps2: largest sampled speed and acceleration.
        min_obstacle_distance_m: smallest sampled field distance (inf without field).
        min_swarm_margin_m: smallest sampled ``||E^{1/2}(p - p_n)|| - r_n`` (inf without neighbours).
    """

    vel: float
    acc: float
    obstacle: float
    swarm: float
    grad_by_coeffs: np.ndarray
    grad_by_times: np.ndarray
    max_speed_mps: float
    max_acc_mps2: float
    min_obstacle_distance_m: float
    min_swarm_margin_m: float

    @property
    def total(self) -> float:
        """Sum of the weighted penalties."""
        return self.vel + self.acc + self.obstacle + self.swarm


class TrajectoryCost:
    """The sampled penalties of one planning problem (fixed field, neighbours and start time).

    Args:
        params: limits, clearances, weights, K.
        t0_s: absolute time [s] of the trajectory start.
        distance_field: obstacle field or None (no obstacle term).
        neighbors: predictions of the other drones (may be empty).
        start_world: (3,) trajectory start position [m]; with it, neighbours it is already
            inside the clearance of get the relaxed clearance (module docstring); None: none do.
    """

    def __init__(
        self,
        params: PenaltyParameters,
        t0_s: float,
        distance_field: DistanceField | None,
        neighbors: list[NeighborPrediction],
        start_world: np.ndarray | None = None,
    ):
        self.params = params
        self.t0_s = float(t0_s)
        self.distance_field = distance_field
        self.neighbors = NeighborTable(list(neighbors))
        if start_world is not None:
            self.neighbors.set_start_deficits(start_world, self.t0_s, params)
        #: (distance (nx, ny, nz) float64 [m], origin (3,) [m], voxel [m]) when the field is an
        #: OccupancySnapshot: its trilinear ESDF is then evaluated by a compiled kernel (same formula)
        self.grid = None
        if isinstance(distance_field, OccupancySnapshot):
            self.grid = (
                np.ascontiguousarray(distance_field.distance_m, dtype=np.float64),
                np.ascontiguousarray(distance_field.origin_world, dtype=np.float64),
                float(distance_field.voxel_m),
            )
        p = params
        #: (15,) kernel parameters (v_max, a_max, C_o + margin, C_s + margin, 1/c, n_sigma, r_max, w_v, w_a, w_o, w_s,
        #: rho, z_lo, z_hi, w_z)
        self.parameter_vector = np.array(
            [
                p.limits.v_max_mps,
                p.limits.a_max_mps2,
                p.obstacle_clearance_m + p.clearance_margin_m,
                p.swarm_clearance_m + p.clearance_margin_m,
                1.0 / p.swarm_z_scale,
                p.uncertainty_sigma,
                p.max_uncertainty_inflation_m,
                p.weight_vel,
                p.weight_acc,
                p.weight_obstacle,
                p.weight_swarm,
                p.swarm_recovery_mps,
                p.altitude_band_m[0],
                p.altitude_band_m[1],
                p.weight_altitude,
            ]
        )
        self._out = np.zeros(8)
        self._no_dist = np.zeros(0)
        self._no_grad = np.zeros((0, 3))

    def sample_positions(self, coeffs: np.ndarray, durations: np.ndarray) -> np.ndarray:
        """(M (K+1), 3) sample positions [m] for coefficients (6M, 3) and durations (M,) [s]."""
        return _sample_positions(coeffs, durations, self.params.samples_per_piece)

    def distance_and_gradient(self, points_world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Field distance (n,) [m] and gradient (n, 3) at ``points_world`` (n, 3); requires a field."""
        if self.grid is not None:
            return trilinear_compiled(self.grid[0], self.grid[1], self.grid[2], points_world)
        d, gd = self.distance_field.distance_and_gradient(points_world)
        return np.ascontiguousarray(d, dtype=float), np.ascontiguousarray(gd, dtype=float)

    def accumulate(
        self, coeffs: np.ndarray, durations: np.ndarray, gdc: np.ndarray, gdt: np.ndarray, stats: bool = True
    ) -> np.ndarray:
        """Add partial gradients into ``gdc`` (6M, 3) and ``gdt`` (M,); return (8,) [vel, acc, obstacle, swarm,
        max speed, max acc, min obstacle distance, min swarm margin]. With ``stats`` False the last entry is
        not computed (inf), which lets far neighbours be skipped; the penalties are the same."""
        K = self.params.samples_per_piece
        if self.distance_field is not None:
            d, gd = self.distance_and_gradient(_sample_positions(coeffs, durations, K))
            use_field = True
        else:
            d, gd, use_field = self._no_dist, self._no_grad, False
        nb = self.neighbors
        _penalty_kernel(
            coeffs, durations, K, self.t0_s, self.parameter_vector, d, gd, use_field,
            nb.times_s, nb.pos_world, nb.vel_world, nb.offsets, nb.t_last_s, nb.radius_terms,
            gdc, gdt, self._out, stats,
        )  # fmt: skip
        return self._out.copy()

    def evaluate(self, coeffs: np.ndarray, durations: np.ndarray) -> PenaltyTerms:
        """Penalty values and partial gradients for coefficients (6M, 3) and durations (M,) [s]."""
        gdc = np.zeros_like(coeffs)
        gdt = np.zeros(durations.shape[0])
        o = self.accumulate(coeffs, durations, gdc, gdt)
        return PenaltyTerms(
            *(float(v) for v in o[:4]), gdc, gdt, *(float(v) for v in o[4:8])
        )
