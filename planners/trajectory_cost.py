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
* swarm (MP-CDE Eq. 16): ``v = (C_s + margin + r_n(t))^2 - ||E^{1/2} (p(t) - p_n(t))||^2``
  against each neighbour prediction ``p_n`` evaluated at the same absolute time,
  ``E = diag(1, 1, 1/c)``. Eq. 16 is garbled in our copy of the paper; we read it
  as EGO-Swarm's form, summed over samples, cubed for smoothness, and integrated
  over time like the other penalties. ``r_n(t)`` inflates the clearance by the
  prediction's uncertainty: ``r_n = min(n_sigma sqrt(tr P_pos(t)), r_max)``, the
  same radius as ``NeighborPrediction.uncertainty_radius`` (0 for exact radio
  plans), capped so that an old track cannot block the whole space.

The gradient by ``T_i`` collects the growth of the sample spacing, the motion of
the sample along the piece, and (swarm term only) the dependence of the
neighbour's position and radius on the absolute sample time, which moves with
every ``T_k``, ``k <= i``. The kernels are numba-compiled; the distance field is
called once per evaluation on all samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit

from perception.types import DistanceField, NeighborPrediction

__all__ = ["NeighborTable", "PenaltyParameters", "PenaltyTerms", "TrajectoryCost"]


@dataclass(frozen=True)
class PenaltyParameters:
    """Limits, clearances and weights of the sampled penalties (module docstring).

    Attributes:
        v_max_mps: speed limit [m/s].
        a_max_mps2: acceleration limit [m/s^2].
        obstacle_clearance_m: clearance C_o to obstacles on the distance field [m].
        swarm_clearance_m: swarm clearance C_s [m] (MP-CDE Table I: 0.7 m).
        swarm_z_scale: c in E = diag(1, 1, 1/c), c >= 1 (MP-CDE Eq. 16; not given
            in the paper, 2.0 means 1.41 C_s of vertical clearance).
        clearance_margin_m: added to both clearances inside the penalty [m], so
            that the soft constraint settles outside C_o and C_s.
        uncertainty_sigma: n_sigma of the neighbour uncertainty radius [-].
        max_uncertainty_inflation_m: cap r_max on the inflation [m].
        weight_vel: weight of the speed penalty [-].
        weight_acc: weight of the acceleration penalty [-].
        weight_obstacle: weight of the obstacle penalty [-].
        weight_swarm: weight of the swarm penalty w_s [-].
        samples_per_piece: K, sample intervals per piece [-].
    """

    v_max_mps: float = 2.0
    a_max_mps2: float = 4.0
    obstacle_clearance_m: float = 0.4
    swarm_clearance_m: float = 0.7
    swarm_z_scale: float = 2.0
    clearance_margin_m: float = 0.1
    uncertainty_sigma: float = 1.0
    max_uncertainty_inflation_m: float = 1.0
    weight_vel: float = 1.0e4
    weight_acc: float = 1.0e4
    weight_obstacle: float = 1.0e4
    weight_swarm: float = 1.0e4
    samples_per_piece: int = 16

    def __post_init__(self) -> None:
        for name in ("v_max_mps", "a_max_mps2", "swarm_clearance_m"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name}={getattr(self, name)!r}: must be > 0")
        for name in (
            "obstacle_clearance_m",
            "clearance_margin_m",
            "uncertainty_sigma",
            "max_uncertainty_inflation_m",
            "weight_vel",
            "weight_acc",
            "weight_obstacle",
            "weight_swarm",
        ):
            if not getattr(self, name) >= 0.0:
                raise ValueError(f"{name}={getattr(self, name)!r}: must be >= 0")
        if not self.swarm_z_scale >= 1.0:
            raise ValueError(f"swarm_z_scale={self.swarm_z_scale!r}: must be >= 1")
        if not (isinstance(self.samples_per_piece, int) and self.samples_per_piece >= 2):
            raise ValueError(f"samples_per_piece={self.samples_per_piece!r}: must be an int >= 2")


class NeighborTable:
    """Neighbour predictions packed into flat arrays for the compiled kernels.

    Attributes:
        times_s: (sum K,) sample times [s] of all neighbours, concatenated.
        pos_world: (sum K, 3) positions [m]; vel_world: (sum K, 3) velocities [m/s].
        offsets: (N+1,) start of neighbour n's samples.
        t_last_s: (N,) last sample time [s] (covariance grows after it).
        cov_trace_poly: (N, 3) ``(a, b, c)`` with ``tr P_pos(t) = a + b dt + c dt^2``, dt = max(t - t_last, 0).
    """

    def __init__(self, neighbors: list[NeighborPrediction]):
        n = len(neighbors)
        self.times_s = np.concatenate([np.asarray(nb.times_s, float) for nb in neighbors]) if n else np.zeros(0)
        self.pos_world = np.concatenate([np.asarray(nb.pos_world, float) for nb in neighbors]) if n else np.zeros((0, 3))
        self.vel_world = np.concatenate([np.asarray(nb.vel_world, float) for nb in neighbors]) if n else np.zeros((0, 3))
        self.offsets = np.zeros(n + 1, dtype=np.int64)
        self.offsets[1:] = np.cumsum([np.shape(nb.times_s)[0] for nb in neighbors]).astype(np.int64)
        self.t_last_s = np.array([float(nb.times_s[-1]) for nb in neighbors]) if n else np.zeros(0)
        self.cov_trace_poly = np.zeros((n, 3))
        for k, nb in enumerate(neighbors):
            P = np.asarray(nb.cov_world, float)
            # tr P_pos(t) = tr Ppp + dt tr(Ppv + Ppv^T) + dt^2 tr Pvv   (perception.types, MP-CDE Eq. 12)
            self.cov_trace_poly[k] = (np.trace(P[:3, :3]), 2.0 * np.trace(P[:3, 3:]), np.trace(P[3:, 3:]))

    @property
    def count(self) -> int:
        """Number of neighbours N."""
        return int(self.t_last_s.shape[0])


@dataclass(frozen=True)
class PenaltyTerms:
    """Weighted penalty values, their partial gradients and sample statistics.

    Attributes:
        vel, acc, obstacle, swarm: weighted penalty integrals [-].
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


@njit(cache=True)
def _sample_positions(coeffs, T, K):
    """Positions (M (K+1), 3) [m] at ``t_ij = j T_i / K``."""
    m = T.shape[0]
    out = np.empty((m * (K + 1), 3))
    for i in range(m):
        for j in range(K + 1):
            s = j * T[i] / K
            for d in range(3):
                acc = 0.0
                for r in range(5, -1, -1):
                    acc = acc * s + coeffs[6 * i + r, d]
                out[i * (K + 1) + j, d] = acc
    return out


@njit(cache=True)
def _neighbor_state(ts, ps, vs, lo, hi, t, out_p, out_v):
    """Cubic Hermite position and its time derivative of one neighbour (NeighborPrediction.position)."""
    if t <= ts[lo] or hi - lo == 1:
        k = lo if t <= ts[lo] else hi - 1
        for d in range(3):
            out_p[d] = ps[k, d] + vs[k, d] * (t - ts[k])
            out_v[d] = vs[k, d]
        return
    if t >= ts[hi - 1]:
        for d in range(3):
            out_p[d] = ps[hi - 1, d] + vs[hi - 1, d] * (t - ts[hi - 1])
            out_v[d] = vs[hi - 1, d]
        return
    i = lo
    while ts[i + 1] < t:
        i += 1
    h = ts[i + 1] - ts[i]
    s = (t - ts[i]) / h
    s2 = s * s
    s3 = s2 * s
    h00, h10, h01, h11 = 2 * s3 - 3 * s2 + 1, s3 - 2 * s2 + s, -2 * s3 + 3 * s2, s3 - s2
    d00, d10, d01, d11 = 6 * s2 - 6 * s, 3 * s2 - 4 * s + 1, -6 * s2 + 6 * s, 3 * s2 - 2 * s
    for d in range(3):
        out_p[d] = h00 * ps[i, d] + h10 * h * vs[i, d] + h01 * ps[i + 1, d] + h11 * h * vs[i + 1, d]
        out_v[d] = (d00 * ps[i, d] + d01 * ps[i + 1, d]) / h + d10 * vs[i, d] + d11 * vs[i + 1, d]


@njit(cache=True)
def _penalty_kernel(
    coeffs, T, K, t0, prm, dist, dist_grad, use_field, nb_t, nb_p, nb_v, nb_off, nb_tlast, nb_cov, gdc, gdt, out
):
    """Add the penalty partial gradients to gdc (6M, 3), gdt (M,); write terms and statistics to out (8,).

    prm = (v_max, a_max, C_o + margin, C_s + margin, 1/c, n_sigma, r_max, w_v, w_a, w_o, w_s).
    """
    v_max, a_max, c_obs, c_sw, inv_c, n_sig, r_max = prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6]
    w_v, w_a, w_o, w_s = prm[7], prm[8], prm[9], prm[10]
    m = T.shape[0]
    n_nb = nb_tlast.shape[0]
    vmax2 = v_max * v_max
    amax2 = a_max * a_max
    piece_tgrad = np.zeros(m)
    pn = np.empty(3)
    vn = np.empty(3)
    pos = np.empty(3)
    vel = np.empty(3)
    acc = np.empty(3)
    jer = np.empty(3)
    g_p = np.empty(3)
    g_v = np.empty(3)
    g_a = np.empty(3)
    beta0 = np.empty(6)
    beta1 = np.empty(6)
    beta2 = np.empty(6)
    for k in range(8):
        out[k] = 0.0
    out[6] = np.inf
    out[7] = np.inf
    t_start = t0
    for i in range(m):
        step = T[i] / K
        for j in range(K + 1):
            s1 = j * step
            alpha = j / K
            omg = 0.5 if (j == 0 or j == K) else 1.0
            beta0[0] = 1.0
            for r in range(1, 6):
                beta0[r] = beta0[r - 1] * s1
            beta1[0] = 0.0
            beta2[0] = 0.0
            beta2[1] = 0.0
            for r in range(1, 6):
                beta1[r] = r * beta0[r - 1]
            for r in range(2, 6):
                beta2[r] = r * (r - 1) * beta0[r - 2]
            for d in range(3):
                c = coeffs[6 * i : 6 * i + 6, d]
                pos[d] = c[0] + s1 * (c[1] + s1 * (c[2] + s1 * (c[3] + s1 * (c[4] + s1 * c[5]))))
                vel[d] = c[1] + s1 * (2 * c[2] + s1 * (3 * c[3] + s1 * (4 * c[4] + s1 * 5 * c[5])))
                acc[d] = 2 * c[2] + s1 * (6 * c[3] + s1 * (12 * c[4] + s1 * 20 * c[5]))
                jer[d] = 6 * c[3] + s1 * (24 * c[4] + s1 * 60 * c[5])
                g_p[d] = 0.0
                g_v[d] = 0.0
                g_a[d] = 0.0
            node = 0.0
            g_t = 0.0  # d node / d t_abs (explicit)
            v2 = vel[0] * vel[0] + vel[1] * vel[1] + vel[2] * vel[2]
            a2 = acc[0] * acc[0] + acc[1] * acc[1] + acc[2] * acc[2]
            out[4] = max(out[4], np.sqrt(v2))
            out[5] = max(out[5], np.sqrt(a2))
            viol = v2 - vmax2  # ||v||^2 - v_max^2
            if viol > 0.0 and w_v > 0.0:
                pen = w_v * viol * viol * viol
                node += pen
                out[0] += omg * step * pen
                for d in range(3):
                    g_v[d] += w_v * 3.0 * viol * viol * 2.0 * vel[d]
            viol = a2 - amax2  # ||a||^2 - a_max^2
            if viol > 0.0 and w_a > 0.0:
                pen = w_a * viol * viol * viol
                node += pen
                out[1] += omg * step * pen
                for d in range(3):
                    g_a[d] += w_a * 3.0 * viol * viol * 2.0 * acc[d]
            if use_field:
                idx = i * (K + 1) + j
                if not dist[idx] == dist[idx]:  # NaN from the field poisons the cost (the optimiser raises)
                    out[2] = np.nan
                out[6] = min(out[6], dist[idx])
                viol = c_obs - dist[idx]  # (C_o + margin) - d(p)
                if viol > 0.0 and w_o > 0.0:
                    pen = w_o * viol * viol * viol
                    node += pen
                    out[2] += omg * step * pen
                    for d in range(3):
                        g_p[d] -= w_o * 3.0 * viol * viol * dist_grad[idx, d]
            t_abs = t_start + s1
            for n in range(n_nb):
                _neighbor_state(nb_t, nb_p, nb_v, nb_off[n], nb_off[n + 1], t_abs, pn, vn)
                dt = t_abs - nb_tlast[n]
                r = 0.0
                dr = 0.0
                if dt > 0.0 and n_sig > 0.0:
                    tr = nb_cov[n, 0] + nb_cov[n, 1] * dt + nb_cov[n, 2] * dt * dt
                    if tr > 0.0:
                        r = n_sig * np.sqrt(tr)  # r_n = n_sigma sqrt(tr P_pos(t))
                        dr = n_sig * (nb_cov[n, 1] + 2.0 * nb_cov[n, 2] * dt) / (2.0 * np.sqrt(tr))
                elif n_sig > 0.0:
                    r = n_sig * np.sqrt(max(nb_cov[n, 0], 0.0))
                if r > r_max:
                    r = r_max
                    dr = 0.0
                dx = pos[0] - pn[0]
                dy = pos[1] - pn[1]
                dz = pos[2] - pn[2]
                ell2 = dx * dx + dy * dy + dz * dz * inv_c  # ||E^{1/2}(p - p_n)||^2
                out[7] = min(out[7], np.sqrt(ell2) - r)
                clr = c_sw + r
                viol = clr * clr - ell2  # MP-CDE Eq. 16
                if viol > 0.0 and w_s > 0.0:
                    pen = w_s * viol * viol * viol
                    node += pen
                    out[3] += omg * step * pen
                    gv = w_s * 3.0 * viol * viol
                    g_p[0] -= gv * 2.0 * dx
                    g_p[1] -= gv * 2.0 * dy
                    g_p[2] -= gv * 2.0 * dz * inv_c
                    # d viol / d t_abs = 2 clr dr/dt + 2 (E d) . v_n
                    g_t += gv * (2.0 * clr * dr + 2.0 * (dx * vn[0] + dy * vn[1] + dz * inv_c * vn[2]))
            if node == 0.0 and g_t == 0.0:
                continue
            w = omg * step
            for r in range(6):
                for d in range(3):
                    gdc[6 * i + r, d] += w * (beta0[r] * g_p[d] + beta1[r] * g_v[d] + beta2[r] * g_a[d])
            chain = g_p[0] * vel[0] + g_p[1] * vel[1] + g_p[2] * vel[2]
            chain += g_v[0] * acc[0] + g_v[1] * acc[1] + g_v[2] * acc[2]
            chain += g_a[0] * jer[0] + g_a[1] * jer[1] + g_a[2] * jer[2]
            gdt[i] += omg * node / K + w * alpha * (chain + g_t)
            piece_tgrad[i] += w * g_t
        t_start += T[i]
    acc_t = 0.0  # t_abs of piece i moves with every T_k, k < i
    for i in range(m - 1, 0, -1):
        acc_t += piece_tgrad[i]
        gdt[i - 1] += acc_t


class TrajectoryCost:
    """The sampled penalties of one planning problem (fixed field, neighbours and start time).

    Args:
        params: limits, clearances, weights, K.
        t0_s: absolute time [s] of the trajectory start.
        distance_field: obstacle field or None (no obstacle term).
        neighbors: predictions of the other drones (may be empty).
    """

    def __init__(
        self,
        params: PenaltyParameters,
        t0_s: float,
        distance_field: DistanceField | None,
        neighbors: list[NeighborPrediction],
    ):
        self.params = params
        self.t0_s = float(t0_s)
        self.distance_field = distance_field
        self.neighbors = NeighborTable(list(neighbors))
        p = params
        #: (11,) kernel parameters (v_max, a_max, C_o + margin, C_s + margin, 1/c, n_sigma, r_max, w_v, w_a, w_o, w_s)
        self.parameter_vector = np.array(
            [
                p.v_max_mps,
                p.a_max_mps2,
                p.obstacle_clearance_m + p.clearance_margin_m,
                p.swarm_clearance_m + p.clearance_margin_m,
                1.0 / p.swarm_z_scale,
                p.uncertainty_sigma,
                p.max_uncertainty_inflation_m,
                p.weight_vel,
                p.weight_acc,
                p.weight_obstacle,
                p.weight_swarm,
            ]
        )
        self._out = np.zeros(8)
        self._no_dist = np.zeros(0)
        self._no_grad = np.zeros((0, 3))

    def sample_positions(self, coeffs: np.ndarray, durations: np.ndarray) -> np.ndarray:
        """(M (K+1), 3) sample positions [m] for coefficients (6M, 3) and durations (M,) [s]."""
        return _sample_positions(coeffs, durations, self.params.samples_per_piece)

    def accumulate(self, coeffs: np.ndarray, durations: np.ndarray, gdc: np.ndarray, gdt: np.ndarray) -> np.ndarray:
        """Add partial gradients into ``gdc`` (6M, 3) and ``gdt`` (M,); return (8,) [vel, acc, obstacle, swarm,
        max speed, max acc, min obstacle distance, min swarm margin]."""
        K = self.params.samples_per_piece
        if self.distance_field is not None:
            d, gd = self.distance_field.distance_and_gradient(_sample_positions(coeffs, durations, K))
            d = np.ascontiguousarray(d, dtype=float)
            gd = np.ascontiguousarray(gd, dtype=float)
            use_field = True
        else:
            d, gd, use_field = self._no_dist, self._no_grad, False
        nb = self.neighbors
        _penalty_kernel(
            coeffs, durations, K, self.t0_s, self.parameter_vector, d, gd, use_field,
            nb.times_s, nb.pos_world, nb.vel_world, nb.offsets, nb.t_last_s, nb.cov_trace_poly,
            gdc, gdt, self._out,
        )  # fmt: skip
        return self._out.copy()

    def evaluate(self, coeffs: np.ndarray, durations: np.ndarray) -> PenaltyTerms:
        """Penalty values and partial gradients for coefficients (6M, 3) and durations (M,) [s]."""
        gdc = np.zeros_like(coeffs)
        gdt = np.zeros(durations.shape[0])
        o = self.accumulate(coeffs, durations, gdc, gdt)
        return PenaltyTerms(
            float(o[0]), float(o[1]), float(o[2]), float(o[3]), gdc, gdt, float(o[4]), float(o[5]), float(o[6]), float(o[7])
        )
