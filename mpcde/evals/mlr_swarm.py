"""Round-based MLR-DMPC swarm over the simulated radio (DMPC-Swarm Sec. 3-5): N UAVs, M CUs, metrics.

The driver connects :mod:`planners.dmpc.mlr` (CUs and UAVs) through one
:class:`sim.radio.Radio` with N + M nodes (UAVs 0..N-1, CU w is node N + w,
at a fixed position), so Bernoulli / Gilbert-Elliott loss, range and jamming
windows apply to every message. Round k (DMPC-Swarm Fig. 1): at kT every UAV
switches its reference (Eq. 10) and every CU computes (Alg. 1) with the
messages of round k - 1; at kT + T_calc every node broadcasts (one radio
message per slot); the messages are read at (k + 1)T.

"CUs deaf from t1 to t2" (the paper's Fig. 4 / Sec. 5.4 experiment: "CUs
can transmit but cannot receive") is applied here, because the radio's
jamming windows deafen every receiver: a message whose delivery time falls in
such a window is dropped at a CU receiver (counted in ``cu_deaf_drops``).

UAV motion (Assumption 1): each UAV is exactly on its nominal reference,
plus an optional bounded disturbance ||d_i(t)|| <= ``disturbance_m`` (three
sines of seeded phases, 0.3-0.7 Hz). A reference switch that is not
continuous (only the ignore-loss baseline produces them: its CUs may start a
new trajectory from a stale belief of where the UAV is) is flown with a
critically damped tracking transient, e'' + 2 w e' + w^2 e = 0 with w =
``tracking_natural_freq_rad_s``, from the position and velocity offset at the
switch: the actual position stays continuous and converges to the new
reference (a stand-in for the low-level controller; Assumption 1 does not
hold during it). MLR-DMPC's switches are always continuous (checked:
``max_reference_jump_m``). In this kinematic model the baseline's failure
in the Fig. 4 setting (:mod:`mpcde.evals.mlr`) is not certain: it depends on
which stale beliefs meet (per seed: docs/results/mlr_dmpc.md#eval-mlr-fig-3b-3c-and-4-in-the-kinematic-swarm).

Collisions are pairs whose ellipsoidal distance ||Theta^-1 (p_i - p_j)|| of
the ACTUAL positions is below ``collision_distance_m`` at any time of a fine
grid (``fine_steps_per_round`` per round), not only at round boundaries.
With d̂_min = 0.45 m planned at T_c = 0.2 s and d_min = 0.25 m checked, the
margin covers the motion between checks (Theorem 3: two UAVs at the per-axis
speed limit v_max_mps = 1 m/s approach by at most about 0.3 m (scaled) in half a
check interval; sqrt(0.45^2 - 0.3^2) = 0.34 m > 0.25 m).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from planners.dmpc.collision import ellipsoidal_distance
from planners.dmpc.mlr.compute_unit import ComputeUnit, CuStepReport, planned_motion_m, summarize_reports
from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.trajectory import ReferenceTrajectory
from planners.dmpc.mlr.uav import Uav, initial_trajectory
from sim.checks import ConfigError, require_boolean, require_integer_at_least, require_non_negative, require_positive
from sim.radio import Radio, RadioConfig

__all__ = ["MlrRunResult", "MlrSwarmConfig", "run_mlr_swarm"]


@dataclass(frozen=True)
class MlrSwarmConfig:
    """Settings of one swarm run.

    Attributes:
        mlr: the MLR-DMPC settings (N, M, T, QP...).
        radio: the channel (its ``rate_hz`` is not used: one broadcast per slot and round).
        seed: seed of the radio and of the disturbance phases.
        duration_s: longest simulated time [s]; the run stops earlier once the
            last formation is reached.
        ignore_message_loss: fly the Sec. 5.4 baseline (Gräfe et al. 2022) instead of MLR-DMPC.
        cu_deaf_windows_s: ((t1, t2), ...) [s] in which CUs receive nothing (closed-open).
        calc_s: T_calc, start of the communication phase within a round [s]
            (Sec. 5.1: 0.105 s of 0.2 s; chosen 0.1). ``radio.delay_s`` must
            end before the next round: calc_s + delay_s < T.
        collision_distance_m: d_min of Eq. 2 for the collision metric [m]
            (chosen 0.25, the paper's Crazyflie distance).
        arrival_tolerance_m: a formation is reached when every UAV is within
            this of its target [m] (chosen 0.1).
        fine_steps_per_round: samples per round of the collision check (chosen 10: 20 ms).
        tracking_natural_freq_rad_s: w of the tracking transient after a
            discontinuous reference switch [rad/s] (chosen 4).
        disturbance_m: bound on the actual-minus-reference offset [m] (chosen 0).
        cu_positions_world: ((x, y, z), ...) M CU positions [m], or () for
            points on a 4 m circle at z = 0.5 m (only the radio's range uses them).
    """

    mlr: MlrConfig = field(default_factory=MlrConfig)
    radio: RadioConfig = field(default_factory=RadioConfig)
    seed: int = 0
    duration_s: float = 30.0
    ignore_message_loss: bool = False
    cu_deaf_windows_s: tuple[tuple[float, float], ...] = ()
    calc_s: float = 0.1
    collision_distance_m: float = 0.25
    arrival_tolerance_m: float = 0.1
    fine_steps_per_round: int = 10
    tracking_natural_freq_rad_s: float = 4.0
    disturbance_m: float = 0.0
    cu_positions_world: tuple[tuple[float, float, float], ...] = ()

    def __post_init__(self) -> None:
        require_integer_at_least("seed", self.seed, 0)
        require_positive("duration_s", self.duration_s)
        require_boolean("ignore_message_loss", self.ignore_message_loss)
        for w in self.cu_deaf_windows_s:
            if len(w) != 2 or not w[0] < w[1]:
                raise ConfigError("cu_deaf_windows_s", self.cu_deaf_windows_s, "pairs (t1, t2) with t1 < t2")
        require_positive("calc_s", self.calc_s)
        if not self.calc_s + self.radio.delay_s < self.mlr.round_s:
            raise ConfigError("calc_s", self.calc_s, f"calc_s + radio.delay_s < round_s={self.mlr.round_s}")
        require_positive("collision_distance_m", self.collision_distance_m)
        require_positive("arrival_tolerance_m", self.arrival_tolerance_m)
        require_integer_at_least("fine_steps_per_round", self.fine_steps_per_round, 1)
        require_positive("tracking_natural_freq_rad_s", self.tracking_natural_freq_rad_s)
        require_non_negative("disturbance_m", self.disturbance_m)
        if self.cu_positions_world and np.shape(self.cu_positions_world) != (self.mlr.n_cus, 3):
            raise ConfigError("cu_positions_world", self.cu_positions_world, f"n_cus={self.mlr.n_cus} (x, y, z) points")

    def cu_deaf(self, time_s: float) -> bool:
        """Whether CUs receive nothing at ``time_s`` [s]."""
        return any(t1 <= time_s < t2 for t1, t2 in self.cu_deaf_windows_s)


@dataclass(frozen=True)
class MlrRunResult:
    """Metrics of one run.

    Attributes:
        collisions: distinct UAV pairs that came closer than d_min (actual positions, fine grid).
        collision_pairs: those pairs (i, j), i < j, with the first time [s].
        min_distance_m: smallest ellipsoidal distance between any two UAVs [m].
        arrival_time_s: time at which the LAST formation was reached [s] (NaN if never).
        formation_times_s: time from each formation's start to its arrival [s] (NaN if not reached).
        rounds: rounds simulated.
        rounds_with_mlr: rounds in which at least one CU requested or donated.
        deprecated_trackers: tracker deprecations summed over CUs and rounds.
        recovery_requests: recovery requests sent.
        qp_solves: QPs solved; qp_failures: QPs OSQP did not solve.
        qp_solve_ms_median / qp_solve_ms_max: OSQP update + solve wall time [ms].
        qp_step_ms_median: build + solve wall time of a CU's QP [ms].
        qp_iterations_median: median OSQP iterations.
        max_reference_jump_m: largest position jump of a reference at a switch [m].
        cu_deaf_drops: messages dropped at deaf CUs.
        cu_rounds, cu_modes, deprecations_by_cause, rounds_all_deprecated,
            recovery_answered: where the CU rounds went
            (:func:`planners.dmpc.mlr.compute_unit.summarize_reports`).
        halts_begun / halts_released: times a UAV came to rest on its
            reference (motion left in it < ``MlrConfig.deadlock_motion_m``)
            away from its target (farther than ``arrival_tolerance_m``), and
            times such a UAV's reference moved it on; halted_uav_rounds: UAV
            rounds spent so.
        radio: the radio's counts (sent, delivered, lost by cause).
        positions_world: (rounds + 1, N, 3) actual positions at the round boundaries [m].
    """

    collisions: int
    collision_pairs: tuple[tuple[int, int, float], ...]
    min_distance_m: float
    arrival_time_s: float
    formation_times_s: tuple[float, ...]
    rounds: int
    rounds_with_mlr: int
    deprecated_trackers: int
    recovery_requests: int
    qp_solves: int
    qp_failures: int
    qp_solve_ms_median: float
    qp_solve_ms_max: float
    qp_step_ms_median: float
    qp_iterations_median: float
    max_reference_jump_m: float
    cu_deaf_drops: int
    cu_rounds: int
    cu_modes: dict[str, int]
    deprecations_by_cause: dict[str, int]
    rounds_all_deprecated: int
    recovery_answered: int
    halts_begun: int
    halts_released: int
    halted_uav_rounds: int
    radio: dict[str, Any]
    positions_world: np.ndarray = field(repr=False, compare=False)

    def metrics(self) -> dict[str, Any]:
        """Every metric but the positions, JSON-ready."""
        out = {k: v for k, v in asdict(self).items() if k != "positions_world"}
        out["collision_pairs"] = [list(p) for p in self.collision_pairs]
        out["formation_times_s"] = list(self.formation_times_s)
        return out


_SUMMARY_FIELDS = (
    "rounds_with_mlr", "deprecated_trackers", "recovery_requests", "qp_failures", "qp_solve_ms_median", "qp_solve_ms_max",
    "qp_step_ms_median", "qp_iterations_median", "cu_rounds", "cu_modes", "deprecations_by_cause", "rounds_all_deprecated",
    "recovery_answered",
)  # fmt: skip
"""The :class:`MlrRunResult` fields that :func:`summarize_reports` gives under the same name."""


class _Motion:
    """Actual UAV positions: reference + tracking transient + disturbance (see the module docstring)."""

    def __init__(self, n: int, cfg: MlrSwarmConfig) -> None:
        rng = np.random.default_rng([cfg.seed, 0x3D15])
        self.phase = rng.uniform(0.0, 2 * np.pi, (n, 3))
        self.freq = 2 * np.pi * rng.uniform(0.3, 0.7, (n, 3))
        self.amp = cfg.disturbance_m / np.sqrt(3.0)  # ||d|| <= disturbance_m
        self.w = cfg.tracking_natural_freq_rad_s
        self.t_switch = np.zeros(n)
        self.e0 = np.zeros((n, 3))
        self.de0 = np.zeros((n, 3))

    def offset(self, i: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(transient e (n, 3), e' (n, 3)) of UAV i at times t (n,)."""
        s = np.maximum(np.asarray(t, float) - self.t_switch[i], 0.0)[:, None]
        decay = np.exp(-self.w * s)
        c1 = self.de0[i] + self.w * self.e0[i]  # e(s) = (e0 + c1 s) exp(-w s)
        e = (self.e0[i] + c1 * s) * decay
        de = (c1 - self.w * (self.e0[i] + c1 * s)) * decay
        return e, de

    def disturbance(self, i: int, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(d (n, 3), d' (n, 3)) of UAV i at times t (n,)."""
        arg = self.freq[i][None] * np.asarray(t, float)[:, None] + self.phase[i][None]
        return self.amp * np.sin(arg), self.amp * self.freq[i][None] * np.cos(arg)

    def state(self, i: int, ref: ReferenceTrajectory, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Actual (positions (n, 3), velocities (n, 3)) of UAV i at times t (n,)."""
        x = ref.states_at(t)
        e, de = self.offset(i, t)
        d, dd = self.disturbance(i, t)
        return x[:, :3] + e + d, x[:, 3:6] + de + dd

    def switch(self, i: int, old: ReferenceTrajectory, new: ReferenceTrajectory, t: float) -> float:
        """Restart the transient at a switch at ``t``; returns the reference's position jump [m]."""
        tt = np.array([t])
        x_old, x_new = old.states_at(tt)[0], new.states_at(tt)[0]
        e, de = self.offset(i, tt)
        self.e0[i] = x_old[:3] + e[0] - x_new[:3]  # actual position stays continuous
        self.de0[i] = x_old[3:6] + de[0] - x_new[3:6]
        self.t_switch[i] = t
        return float(np.linalg.norm(x_old[:3] - x_new[:3]))


def _cu_positions(cfg: MlrSwarmConfig) -> np.ndarray:
    if cfg.cu_positions_world:
        return np.asarray(cfg.cu_positions_world, float)
    ang = 2 * np.pi * np.arange(cfg.mlr.n_cus) / cfg.mlr.n_cus
    return np.c_[4.0 * np.cos(ang), 4.0 * np.sin(ang), np.full(cfg.mlr.n_cus, 0.5)]


def run_mlr_swarm(
    config: MlrSwarmConfig, start_world: np.ndarray, formations_world: Sequence[np.ndarray]
) -> MlrRunResult:
    """Fly N UAVs from ``start_world`` (N, 3) through the target sets ``formations_world`` [(N, 3), ...].

    Each formation's targets are announced to the UAVs when the previous one
    is reached (all UAVs within ``arrival_tolerance_m``); the UAVs broadcast
    them to the CUs with their state messages.
    """
    cfg, mlr = config, config.mlr
    N, M, T = mlr.n_uavs, mlr.n_cus, mlr.round_s
    start = np.asarray(start_world, float).reshape(N, 3)
    goals = [np.asarray(f, float).reshape(N, 3) for f in formations_world]
    if not goals:
        raise ValueError("formations_world: at least one (N, 3) target set")
    initial = [initial_trajectory(mlr, p) for p in start]
    uavs = [Uav(i, initial[i], goals[0][i]) for i in range(N)]
    cus = [ComputeUnit(mlr, w, initial, goals[0], cfg.ignore_message_loss) for w in range(M)]
    radio = Radio(cfg.radio, N + M, cfg.seed)
    motion = _Motion(N, cfg)
    cu_pos = _cu_positions(cfg)
    inbox: list[list[object]] = [[] for _ in range(N + M)]
    n_rounds = int(np.ceil(cfg.duration_s / T - 1e-9))
    S = cfg.fine_steps_per_round
    formation, formation_start, formation_times = 0, 0.0, [float("nan")] * len(goals)
    reports: list[CuStepReport] = []
    min_dist, pairs, max_jump, deaf_drops = np.inf, {}, 0.0, 0
    positions = [start.copy()]
    iu = np.triu_indices(N, 1)
    halted = np.zeros(N, bool)
    halts_begun = halts_released = halted_rounds = 0
    k = 0
    for k in range(n_rounds):
        t = k * T
        now = np.array([t])
        pos_now, vel_now = np.empty((N, 3)), np.empty((N, 3))
        payloads: list[tuple[int, object]] = []
        for i, uav in enumerate(uavs):
            old = uav.reference
            p, v = motion.state(i, old, now)
            pos_now[i], vel_now[i] = p[0], v[0]
            out, switched = uav.step(k, inbox[i], p[0], v[0])
            if switched:
                max_jump = max(max_jump, motion.switch(i, old, uav.reference, t))
            payloads += [(i, m) for m in out]
            at_rest = planned_motion_m(uav.reference, max(t, uav.reference.t_start_s)) < mlr.deadlock_motion_m
            now_halted = at_rest and float(np.linalg.norm(p[0] - goals[formation][i])) > cfg.arrival_tolerance_m
            halts_begun += int(now_halted and not halted[i])
            halts_released += int(halted[i] and not now_halted)
            halted_rounds += int(now_halted)
            halted[i] = now_halted
        for w, cu in enumerate(cus):
            msg, report = cu.step(k, inbox[N + w])
            reports.append(report)
            if msg is not None:
                payloads.append((N + w, msg))
        node_pos = np.vstack([pos_now, cu_pos])
        for sender, msg in payloads:
            radio.broadcast(sender, t + cfg.calc_s, msg, node_pos)
        # Actual positions on the fine grid of [kT, (k+1)T] for the collision metric.
        tf = t + T * np.arange(S + 1) / S
        fine = np.stack([motion.state(i, uavs[i].reference, tf)[0] for i in range(N)])  # (N, S+1, 3)
        dist = ellipsoidal_distance(fine[iu[0]] - fine[iu[1]], mlr.downwash)  # (pairs, S+1)
        min_dist = min(min_dist, float(dist.min()))
        for p_idx in np.flatnonzero(np.any(dist < cfg.collision_distance_m, axis=1)):
            key = (int(iu[0][p_idx]), int(iu[1][p_idx]))
            if key not in pairs:
                pairs[key] = float(tf[int(np.argmax(dist[p_idx] < cfg.collision_distance_m))])
        positions.append(fine[:, -1].copy())
        t_next = (k + 1) * T
        if np.all(np.linalg.norm(fine[:, -1] - goals[formation], axis=1) < cfg.arrival_tolerance_m):
            formation_times[formation] = t_next - formation_start
            formation += 1
            formation_start = t_next
            if formation == len(goals):
                break
            for i, uav in enumerate(uavs):
                uav.set_target(goals[formation][i])
        for r in range(N + M):
            got = radio.receive(r, t_next)
            if r >= N:
                kept = [m for m in got if not cfg.cu_deaf(m.receive_time_s)]
                deaf_drops += len(got) - len(kept)
                got = kept
            inbox[r] = [m.payload for m in got]
    summary = summarize_reports(reports)
    done = formation == len(goals)
    return MlrRunResult(
        collisions=len(pairs),
        collision_pairs=tuple((i, j, tc) for (i, j), tc in sorted(pairs.items())),
        min_distance_m=float(min_dist),
        arrival_time_s=float((k + 1) * T) if done else float("nan"),
        formation_times_s=tuple(formation_times),
        rounds=k + 1,
        qp_solves=summary["computations"],
        **{name: summary[name] for name in _SUMMARY_FIELDS},
        max_reference_jump_m=max_jump,
        cu_deaf_drops=deaf_drops,
        halts_begun=halts_begun,
        halts_released=halts_released,
        halted_uav_rounds=halted_rounds,
        radio=radio.stats(),
        positions_world=np.array(positions),
    )
