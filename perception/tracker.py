"""Multi-target tracker of neighbours: association, track life cycle, predictions.

MP-CDE Sec. IV-B. Each frame (25 Hz) the tracker

1. predicts every track to the frame time with its constant-velocity filter
   (Eq. 9; :mod:`perception.kalman_cv`), adding a linear covariance inflation to
   tracks unseen for longer than ``t_hold``;
2. associates measured positions to tracks with the Hungarian algorithm
   (``scipy.optimize.linear_sum_assignment``) on the squared Mahalanobis
   distance ``d2 = nu^T S^-1 nu``, ``S = H P^- H^T + R``; pairs with
   ``d2 > gate_chi2`` cost a large constant and are rejected after assignment;
3. updates matched tracks (Eq. 10, adaptive Q by Eq. 11 for ``"akf"``);
4. births a ``tentative`` track from every unmatched measurement farther
   than ``birth_gate_chi2`` from every live track; a track with
   ``confirm_hits`` associated measurements is ``confirmed``; a confirmed track
   unseen for more than ``t_hold_s`` is ``coasting``; any track unseen for more
   than ``t_drop_s`` (tentative: ``tentative_drop_s``) is pruned.

:meth:`MultiTargetTracker.predictions` hands the planners one
:class:`~perception.types.NeighborPrediction` per confirmed or coasting track
(Eq. 12). Two filter back-ends give the same numbers (a test holds them to
1e-9): ``"numba"`` runs all tracks at once in compiled kernels
(:mod:`perception.kalman_kernels`; the default, fast) and ``"filterpy"`` one
filterpy ``KalmanFilter`` per track (the reference). The Hungarian solver is
called only when two gated pairs share a track or a measurement; otherwise
the gated pairs are the assignment (see
:func:`perception.kalman_kernels.trivial_assignment`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from perception.kalman_cv import KalmanCV, predict_batch
from perception.kalman_kernels import gate_pairs, predict_tracks, trivial_assignment, update_tracks
from perception.tracker_config import TrackerConfig
from perception.types import NeighborPrediction

__all__ = [
    "COASTING",
    "CONFIRMED",
    "TENTATIVE",
    "Measurement",
    "MultiTargetTracker",
    "Track",
    "range_noise_cov",
]

TENTATIVE = "tentative"
CONFIRMED = "confirmed"
COASTING = "coasting"

_GATED_COST = 1.0e6  # cost of a pair outside the gate (rejected after assignment)
_TIME_EPS_S = 1e-9  # slack on time comparisons (frame times are sums of floats)


@dataclass(frozen=True)
class Measurement:
    """One measured neighbour position (a back-projected detection, MP-CDE Eq. 7-8).

    Attributes:
        pos_world: (3,) position in world [m].
        cov_world: (3, 3) its covariance [m^2] (grows with range, see :func:`range_noise_cov`).
        time_s: capture time [s].
    """

    pos_world: np.ndarray
    cov_world: np.ndarray
    time_s: float

    def __post_init__(self) -> None:
        if np.shape(self.pos_world) != (3,) or np.shape(self.cov_world) != (3, 3):
            raise ValueError("Measurement: pos_world must be (3,) and cov_world (3, 3)")


def range_noise_cov(range_m: float, std_floor_m: float = 0.02, std_per_range: float = 0.01) -> np.ndarray:
    """Isotropic measurement covariance (3, 3) [m^2] at ``range_m`` [m]: std = floor + per_range * range per axis."""
    std = std_floor_m + std_per_range * float(range_m)
    return std * std * np.eye(3)


@dataclass(frozen=True)
class Track:
    """A snapshot of one track.

    Attributes:
        track_id: identity, unique over the tracker's life.
        status: ``"tentative"``, ``"confirmed"`` or ``"coasting"``.
        time_s: time [s] of the state (the tracker's last update).
        state_world: (6,) ``[p, v]`` [m, m/s].
        cov_world: (6, 6) covariance of the state.
        last_seen_s: time [s] of the last associated measurement.
        hits: number of associated measurements (birth included).
        acc_cov: (3, 3) adaptive acceleration covariance ``A_k`` [m^2/s^4] (zeros for ``"kf"``).
    """

    track_id: int
    status: str
    time_s: float
    state_world: np.ndarray
    cov_world: np.ndarray
    last_seen_s: float
    hits: int
    acc_cov: np.ndarray

    @property
    def pos_world(self) -> np.ndarray:
        """(3,) position [m]."""
        return self.state_world[:3]

    @property
    def vel_world(self) -> np.ndarray:
        """(3,) velocity [m/s]."""
        return self.state_world[3:]


class _CompiledBank:
    """All tracks' filters as stacked arrays, run by the compiled kernels (the fast path)."""

    def __init__(self, config: TrackerConfig) -> None:
        self.cfg = config
        self.x = np.zeros((0, 6))
        self.P = np.zeros((0, 6, 6))
        self.P_post = np.zeros((0, 6, 6))
        self.acc_cov = np.zeros((0, 3, 3))
        self.last_update_s = np.zeros(0)

    def states(self) -> tuple[np.ndarray, np.ndarray]:
        return self.x, self.P

    def predict(self, dt_s: float, coast_s: np.ndarray) -> None:
        c = self.cfg
        predict_tracks(
            self.x, self.P, self.acc_cov, c.sigma_acc_mps2**2, dt_s, coast_s,
            c.coast_pos_inflation_m2ps, c.coast_vel_inflation_m2ps3,
        )  # fmt: skip

    def update(
        self, rows: np.ndarray, cols: np.ndarray, z: np.ndarray, R: np.ndarray, time_s: float,
        S_inv: np.ndarray, adapt: np.ndarray,
    ) -> None:  # fmt: skip
        c = self.cfg
        update_tracks(
            self.x, self.P, self.P_post, self.acc_cov, self.last_update_s, rows, cols, z, R, S_inv, time_s,
            adapt, c.alpha_ema, c.sigma_acc_max_mps2**2, c.adapt_scale,
        )  # fmt: skip

    def add(self, z: np.ndarray, R: np.ndarray, time_s: float) -> None:
        m = z.shape[0]
        x = np.zeros((m, 6))
        x[:, :3] = z
        P = np.zeros((m, 6, 6))
        P[:, :3, :3] = R
        P[:, 3:, 3:] = self.cfg.init_vel_std_mps**2 * np.eye(3)
        self.x = np.concatenate([self.x, x])
        self.P = np.concatenate([self.P, P])
        self.P_post = np.concatenate([self.P_post, P])
        self.acc_cov = np.concatenate([self.acc_cov, np.zeros((m, 3, 3))])
        self.last_update_s = np.concatenate([self.last_update_s, np.full(m, time_s)])

    def keep(self, mask: np.ndarray) -> None:
        self.x, self.P, self.P_post = self.x[mask], self.P[mask], self.P_post[mask]
        self.acc_cov, self.last_update_s = self.acc_cov[mask], self.last_update_s[mask]

    def acc_covs(self) -> np.ndarray:
        return self.acc_cov


class _FilterpyBank:
    """One :class:`~perception.kalman_cv.KalmanCV` (filterpy) per track (the reference path)."""

    def __init__(self, config: TrackerConfig) -> None:
        self.cfg = config
        self.filters: list[KalmanCV] = []

    def states(self) -> tuple[np.ndarray, np.ndarray]:
        if not self.filters:
            return np.zeros((0, 6)), np.zeros((0, 6, 6))
        return np.stack([f.x for f in self.filters]), np.stack([f.P for f in self.filters])

    def predict(self, dt_s: float, coast_s: np.ndarray) -> None:
        c = self.cfg
        rates = np.diag(np.repeat([c.coast_pos_inflation_m2ps, c.coast_vel_inflation_m2ps3], 3))
        for f, coast in zip(self.filters, coast_s):
            f.predict(f.time_s + dt_s, coast * rates if coast > 0 else None)  # P += coast diag(c_p I, c_v I)

    def update(
        self, rows: np.ndarray, cols: np.ndarray, z: np.ndarray, R: np.ndarray, time_s: float,
        S_inv: np.ndarray, adapt: np.ndarray,
    ) -> None:  # fmt: skip
        for i, j in zip(rows, cols):
            self.filters[i].update(z[j], R[j])

    def add(self, z: np.ndarray, R: np.ndarray, time_s: float) -> None:
        c = self.cfg
        for zj, Rj in zip(z, R):
            self.filters.append(
                KalmanCV(
                    zj, Rj, time_s, c.init_vel_std_mps, c.sigma_acc_mps2, c.adaptive,
                    c.alpha_ema, c.sigma_acc_max_mps2, c.adapt_scale, c.adapt_after_hits,
                )  # fmt: skip
            )

    def keep(self, mask: np.ndarray) -> None:
        self.filters = [f for f, k in zip(self.filters, mask) if k]

    def acc_covs(self) -> np.ndarray:
        return np.stack([f.acc_cov for f in self.filters]) if self.filters else np.zeros((0, 3, 3))


class MultiTargetTracker:
    """Tracks neighbours from measured positions (MP-CDE Sec. IV-B); one verb: :meth:`update`.

    Args:
        config: tracker settings (:class:`~perception.tracker_config.TrackerConfig`).
        backend: ``"numba"`` (all tracks at once in compiled kernels,
            :mod:`perception.kalman_kernels`; default) or ``"filterpy"`` (one
            filterpy ``KalmanFilter`` per track; the reference).

    """

    def __init__(self, config: TrackerConfig | None = None, backend: str = "numba") -> None:
        self.config = config if config is not None else TrackerConfig()
        if backend == "numba":
            self._bank: _CompiledBank | _FilterpyBank = _CompiledBank(self.config)
        elif backend == "filterpy":
            self._bank = _FilterpyBank(self.config)
        else:
            raise ValueError(f"backend={backend!r}: 'numba' or 'filterpy'")
        self.backend = backend
        self._time_s: float | None = None
        self._ids = np.zeros(0, dtype=np.int64)
        self._hits = np.zeros(0, dtype=np.int64)
        self._last_seen_s = np.zeros(0)
        self._confirmed = np.zeros(0, dtype=bool)  # ever confirmed
        self._next_id = 0
        self._last_pairs = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64))

    @property
    def last_assignment(self) -> dict[int, int]:
        """``{track_id: measurement index}`` of the last update."""
        return {int(i): int(j) for i, j in zip(*self._last_pairs)}

    @property
    def time_s(self) -> float | None:
        """Time [s] of the last update (None before the first)."""
        return self._time_s

    def _coast_s(self, t_from: float, t_to: float, last_seen_s: np.ndarray, confirmed: np.ndarray) -> np.ndarray:
        """(n,) coasting time [s] accrued over ``[t_from, t_to]`` beyond ``last_seen + t_hold`` (confirmed tracks)."""
        hold = self.config.t_hold_s
        if last_seen_s.size == 0 or t_to <= last_seen_s.min() + hold:
            return np.zeros(last_seen_s.size)
        start = np.maximum(t_from, last_seen_s + hold)
        return np.where(confirmed, np.maximum(t_to - start, 0.0), 0.0)

    def _inflation(self, coast_s: np.ndarray) -> np.ndarray | None:
        """Linear coasting inflation (n, 6, 6) ``coast diag(c_p I, c_v I)`` for coasting times ``coast_s`` (n,)."""
        if not np.any(coast_s > 0):
            return None
        c = self.config
        rates = np.repeat([c.coast_pos_inflation_m2ps, c.coast_vel_inflation_m2ps3], 3)
        return coast_s[:, None, None] * np.diag(rates)[None]  # P += (t - t_hold_start) diag(c_p I, c_v I)

    def update(self, time_s: float, measurements: Sequence[Measurement]) -> None:
        """Process one frame's measurements taken at ``time_s`` [s] (non-decreasing across calls)."""
        t = float(time_s)
        if self._time_s is not None and t < self._time_s:
            raise ValueError(f"time_s={time_s!r}: >= the previous update time {self._time_s!r}")
        m = len(measurements)
        z = np.empty((m, 3))
        R = np.empty((m, 3, 3))
        for j, mm in enumerate(measurements):
            if abs(mm.time_s - t) > 1e-6:
                raise ValueError(f"Measurement.time_s={mm.time_s!r}: equal to the update's time_s={t!r}")
            z[j] = mm.pos_world
            R[j] = mm.cov_world
        cfg = self.config
        n = self._ids.size
        if n and self._time_s is not None:
            self._bank.predict(t - self._time_s, self._coast_s(self._time_s, t, self._last_seen_s, self._confirmed))
        self._time_s = t

        rows = cols = np.zeros(0, dtype=np.int64)
        unmatched = np.ones(m, dtype=bool)
        if n and m:
            x, P = self._bank.states()
            d2 = np.empty((n, m))
            S_inv = np.empty((n, m, 3, 3))
            gate_pairs(x, P, z, R, d2, S_inv)  # d2 = nu^T S^-1 nu, S = H P H^T + R
            rows, cols = np.empty(min(n, m), dtype=np.int64), np.empty(min(n, m), dtype=np.int64)
            k = trivial_assignment(d2, cfg.gate_chi2, rows, cols)
            if k >= 0:  # no two gated pairs share a track or a measurement: they are the assignment
                rows, cols = rows[:k], cols[:k]
            else:  # Hungarian on the gated cost
                rows, cols = linear_sum_assignment(np.where(d2 <= cfg.gate_chi2, d2, _GATED_COST))
                ok = d2[rows, cols] <= cfg.gate_chi2
                rows, cols = rows[ok], cols[ok]
            if rows.size < m:
                unmatched &= ~np.any(d2 <= cfg.birth_gate_chi2, axis=0)  # no births near live tracks
            if rows.size:
                adapt = self._hits[rows] >= cfg.adapt_after_hits
                if not cfg.adaptive:
                    adapt[:] = False
                self._bank.update(rows, cols, z, R, t, S_inv, adapt)  # Eq. 10-11
                self._hits[rows] += 1
                self._last_seen_s[rows] = t
                self._confirmed[rows] |= self._hits[rows] >= cfg.confirm_hits
        self._last_pairs = (self._ids[rows], cols)

        if n and t - self._last_seen_s.min() > min(cfg.t_drop_s, cfg.tentative_drop_s) + _TIME_EPS_S:
            limit = np.where(self._confirmed, cfg.t_drop_s, cfg.tentative_drop_s) + _TIME_EPS_S
            drop = t - self._last_seen_s > limit
            if drop.any():
                keep = ~drop
                self._bank.keep(keep)
                self._ids, self._hits = self._ids[keep], self._hits[keep]
                self._last_seen_s, self._confirmed = self._last_seen_s[keep], self._confirmed[keep]

        if rows.size == m:
            return
        unmatched[cols] = False
        born = np.flatnonzero(unmatched)
        if born.size:
            k = born.size
            self._bank.add(z[born], R[born], t)
            self._ids = np.concatenate([self._ids, np.arange(self._next_id, self._next_id + k)])
            self._next_id += k
            self._hits = np.concatenate([self._hits, np.ones(k, dtype=np.int64)])
            self._last_seen_s = np.concatenate([self._last_seen_s, np.full(k, t)])
            self._confirmed = np.concatenate([self._confirmed, np.full(k, cfg.confirm_hits <= 1)])

    def _status(self) -> list[str]:
        t = self._time_s if self._time_s is not None else 0.0
        coast = t - self._last_seen_s > self.config.t_hold_s + _TIME_EPS_S
        return [COASTING if c and k else (CONFIRMED if c else TENTATIVE) for c, k in zip(self._confirmed, coast)]

    def tracks(self) -> list[Track]:
        """Snapshots of every live track (tentative ones included), in birth order."""
        x, P = self._bank.states()
        acc = self._bank.acc_covs()
        t = float(self._time_s) if self._time_s is not None else 0.0
        return [
            Track(int(i), s, t, x[j].copy(), P[j].copy(), float(self._last_seen_s[j]), int(self._hits[j]), acc[j].copy())
            for j, (i, s) in enumerate(zip(self._ids, self._status()))
        ]

    def predictions(self, time_s: float) -> list[NeighborPrediction]:
        """One :class:`NeighborPrediction` per confirmed or coasting track, propagated to ``time_s`` [s].

        Each track is propagated (Eq. 9, with process noise and coasting
        inflation) from the last update to ``time_s`` and handed over as a
        constant-velocity prediction from there (Eq. 12:
        ``p(t) = p_k + v_k (t - t_k)``, ``P(t) = F P_k F^T``), with ``stamp_s``
        the time the track was last seen, so that ``age_s`` is its staleness.
        """
        if self._time_s is None:
            return []
        t = float(time_s)
        if t < self._time_s:
            raise ValueError(f"time_s={time_s!r}: >= the last update time {self._time_s!r}")
        sel = np.flatnonzero(self._confirmed)
        if sel.size == 0:
            return []
        x, P = self._bank.states()
        acc = self._bank.acc_covs()[sel] + self.config.sigma_acc_mps2**2 * np.eye(3)
        extra = self._inflation(self._coast_s(self._time_s, t, self._last_seen_s[sel], self._confirmed[sel]))
        xs, Ps = predict_batch(x[sel], P[sel], t - self._time_s, acc, extra)
        out = []
        for j, i in enumerate(sel):
            pred = NeighborPrediction.constant_velocity(int(self._ids[i]), "perception", t, xs[j, :3], xs[j, 3:], Ps[j])
            out.append(dataclasses.replace(pred, stamp_s=float(self._last_seen_s[i])))
        return out
