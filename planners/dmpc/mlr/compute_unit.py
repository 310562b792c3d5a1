"""A compute unit (CU) running MLR-DMPC (DMPC-Swarm Alg. 1, Sec. 4.2), or the baseline that ignores loss.

One :meth:`ComputeUnit.step` per round k (computation phase), reading the
messages of round k - 1 and returning what the CU sends in round k's
communication phase:

1. Update the information trackers (Alg. 1 Line 8, Alg. 2:
   :mod:`planners.dmpc.mlr.tracker`). A CU slot of round k - 1 counts as
   accounted for if its CU message arrived, if a recovery reply arrived in it,
   if the CU knows the slot was donated (it heard that CU's request in round
   k - 2), or if it is the CU's own slot.
2. Unify the priorities received in round k - 1 (and the CU's own, if it
   sent some) by the zero-rule maximum (Eq. 11) and form A_ET(k).
3. If the CU requested a trajectory in round k - 1, it donates its slot now:
   it sends nothing (Line 30).
4. Else, if no tracker is deprecated (Lines 14-20): CU w computes the UAV at
   rank (k + w) mod M of A_ET(k), solving QP (13) against every candidate of
   every other UAV; it skips (sends only its priorities) if that UAV's
   unified priority is 0 or its tracker holds two candidates (it was
   recomputed in round k - 1 and its initial state is not known yet), or if
   OSQP fails (then the UAV keeps its trajectory, which is safe).
5. Else MLR (Lines 22-32): it requests the trajectory of one deprecated UAV
   and donates its next slot. Which one the paper does not say. With
   ``lazy_recovery=False`` it is the one at rank (k + w) mod (number
   deprecated), so that several CUs in MLR tend to ask for different UAVs.
   With ``lazy_recovery=True`` (default):

   * a UAV whose state message named a trajectory its tracker lacks
     (``missing``: only a reply can restore it) is asked for first;
   * a UAV that another CU asked for in round k - 1 is not asked for: its
     reply, broadcast in round k, reaches this CU too;
   * if every remaining deprecated tracker became deprecated in this very
     update, for want of the UAV's metadata (Line 13) or of a CU message
     (Line 18), the CU waits one round instead (mode ``"wait"``: a CU
     message with its priorities and no trajectory): the UAVs' state
     messages of round k restore such trackers (Alg. 2 step 1) at the same
     time a reply would, without costing a donated slot. A tracker still
     deprecated one round later is asked for.

   Under loss the eager choice spent about half of all CU rounds requesting
   and donating, mostly for trackers the next state message restored anyway,
   and asked for an arbitrary UAV after a lost CU message although only the
   UAV whose new trajectory was missed needs a reply. The choice changes
   only which message a CU in MLR sends; it computes nothing while any
   tracker is deprecated, so Lemma 1-2 and the collision guarantee are
   untouched.
6. Priorities for round k + 1 (Line 34, Appendix A), 0 for the UAV it just computed.

Start (Remark 2): all CUs start together in round ``first_round`` with the
N initial trajectories; that round has no CU slot of the previous round to
miss. A CU that starts later (``joined_late``, e.g. it had not yet heard
every initial trajectory) may have missed trajectories computed since:
every tracker starts deprecated, and it recovers them like after any loss
(a UAV state message naming a held candidate, or a recovery request).

``ignore_message_loss=True`` is the baseline of Sec. 5.4 (Gräfe et al. 2022):
every received or own new trajectory replaces the one in the store, nothing is
ever deprecated or requested, and the CU always computes its selected UAV
(unless its unified priority is 0).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.qp import MlrProblem, MlrQpResult
from planners.dmpc.mlr.tracker import InformationTrackers, TrackerUpdate
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId, positions_at_each
from planners.dmpc.mlr.trigger import consensus, event_set, quantize, raw_priorities, selected_uav
from planners.dmpc.mlr.types import CuTrajectoryMessage, RecoveryReply, RecoveryRequest, UavStateMessage
from planners.dmpc.sparse_qp.qp_result import DmpcSolveError

__all__ = ["ComputeUnit", "CuStepReport", "planned_motion_m", "summarize_reports"]


@dataclass(frozen=True)
class CuStepReport:
    """What a CU did in one round (for metrics).

    Attributes:
        round_index: k.
        mode: ``"compute"``, ``"idle"`` (selected UAV not computable),
            ``"request"`` (MLR), ``"donate"`` (silent, slot given to a UAV),
            ``"wait"`` (MLR, waiting a round for metadata or another CU's
            reply, see the module docstring) or ``"failed"`` (QP not solved).
        uav_id: the UAV computed or requested (None otherwise).
        a_et: A_ET(k).
        deprecated: UAVs whose tracker is deprecated after the update.
        tracker_update: what Alg. 2 did.
        qp: the QP result when one was solved.
        answered: whether the recovery request this CU sent in round k - 2
            was answered: the requested UAV's reply, sent in the donated slot
            of round k - 1, is in this round's inbox (None when it sent none).
    """

    round_index: int
    mode: str
    uav_id: int | None
    a_et: tuple[int, ...]
    deprecated: tuple[int, ...]
    tracker_update: TrackerUpdate
    qp: MlrQpResult | None = None
    answered: bool | None = None


class ComputeUnit:
    """CU w of Alg. 1.

    Args:
        config: the shared :class:`MlrConfig`.
        cu_index: w in 0..M-1.
        initial: N initial trajectories (Remark 2), known to all CUs.
        initial_targets_world: (N, 3) targets known at start [m] (then from UAV messages).
        ignore_message_loss: run the Sec. 5.4 baseline instead of MLR-DMPC.
        first_round: the round in which all CUs start (see the module docstring).
        joined_late: the CU starts after ``first_round``: every tracker starts deprecated.
    """

    def __init__(
        self,
        config: MlrConfig,
        cu_index: int,
        initial: Sequence[ReferenceTrajectory],
        initial_targets_world: np.ndarray,
        ignore_message_loss: bool = False,
        first_round: int = 0,
        joined_late: bool = False,
    ) -> None:
        if not 0 <= cu_index < config.n_cus:
            raise ValueError(f"cu_index={cu_index!r}: an integer in [0, {config.n_cus - 1}]")
        if len(initial) != config.n_uavs:
            raise ValueError(f"initial: {len(initial)} trajectories, expected n_uavs={config.n_uavs}")
        self.config = config
        self.cu_index = int(cu_index)
        self.ignore_message_loss = bool(ignore_message_loss)
        self.trackers = InformationTrackers(initial, config.max_kept_deprecated)
        self.first_round = int(first_round)
        if joined_late and not self.ignore_message_loss:
            self.trackers.deprecate_all()
        self.targets_world = np.array(initial_targets_world, float).reshape(config.n_uavs, 3)
        self.problem = MlrProblem(config)
        self._own_last: CuTrajectoryMessage | RecoveryRequest | None = None  # what this CU sent last round
        self._donate_now = False
        self._heard_requests: set[int] = set()  # CUs whose request this CU received last round
        self._pending_replies: set[int] = set()  # UAVs asked for by those requests: they reply this round
        self._a_et_prev: tuple[int, ...] | None = None  # A_ET(k - 1) if formed from every CU slot of k - 2
        self._asked: int | None = None  # the UAV requested two rounds ago: its reply is read now
        self._asked_now: int | None = None  # the UAV requested last round

    def step(self, round_index: int, inbox: Sequence[object]) -> tuple[object | None, CuStepReport]:
        """Alg. 1 for round k = ``round_index`` with the payloads received in round k - 1.

        Returns:
            (the payload to broadcast in round k, or None when donating; a :class:`CuStepReport`).
        """
        k, cfg, w = int(round_index), self.config, self.cu_index
        states = {m.uav_id: m for m in inbox if isinstance(m, UavStateMessage)}
        cu_msgs = {m.cu_id: m for m in inbox if isinstance(m, (CuTrajectoryMessage, RecoveryRequest))}
        replies = {m.slot_cu_id: m for m in inbox if isinstance(m, RecoveryReply)}
        for i, m in states.items():
            self.targets_world[i] = m.target_world
        new = {
            m.uav_id: m.trajectory
            for m in cu_msgs.values()
            if isinstance(m, CuTrajectoryMessage) and m.uav_id is not None
        }
        own = self._own_last
        if isinstance(own, CuTrajectoryMessage) and own.uav_id is not None:
            new[own.uav_id] = own.trajectory
        late = {  # step 0 of the tracker: trajectories of round k - 2 sent again (repeat_trajectory)
            m.repeat_uav_id: m.repeat_trajectory
            for m in cu_msgs.values()
            if isinstance(m, CuTrajectoryMessage) and m.repeat_uav_id is not None
        }
        asked, self._asked = self._asked, self._asked_now
        self._asked_now = None
        answered = None if asked is None else (w in replies and replies[w].uav_id == asked)
        missed: list[int] = []
        if self.ignore_message_loss:
            update = self.trackers.update_ignoring_loss(new)
        else:
            missed = [] if k == self.first_round else [  # the first round has no previous round to miss
                v for v in range(cfg.n_cus)
                if not (v == w or v in cu_msgs or v in replies or v in self._heard_requests)
            ]
            suspects: set[int] = set()
            if missed and cfg.precise_cu_loss and self._a_et_prev is not None:
                # Only the UAV that CU v selected in round k - 1 can have a trajectory this CU missed.
                suspects = {selected_uav(self._a_et_prev, k - 1, v, cfg.n_cus) for v in missed}
            update = self.trackers.update(
                {i: m.following for i, m in states.items()}, new,
                {r.uav_id: r.trajectory for r in replies.values()}, not missed or bool(suspects), suspects,
                cfg.max_candidates if cfg.keep_ambiguous else 0, late,
            )  # fmt: skip
        self._heard_requests = {v for v, m in cu_msgs.items() if isinstance(m, RecoveryRequest)}
        self._pending_replies = {m.uav_id for m in cu_msgs.values() if isinstance(m, RecoveryRequest)}
        vectors = [m.priorities for m in cu_msgs.values()] + ([own.priorities] if own is not None else [])
        unified = consensus(vectors, cfg.n_uavs)  # Eq. 11 with the zero rule
        a_et = event_set(unified, cfg.n_cus)
        # A_ET(k) is every computing CU's A_ET(k) when this CU heard every CU slot of round k - 1 (see step 1b).
        self._a_et_prev = a_et if k != self.first_round and not self.ignore_message_loss and not missed else None

        deprecated = self.trackers.deprecated_ids
        if self._donate_now:  # Alg. 1 Line 30: the slot belongs to the requested UAV this round
            self._donate_now = False
            self._own_last = None
            return None, CuStepReport(k, "donate", None, a_et, deprecated, update, answered=answered)
        if deprecated and not self.ignore_message_loss:  # MLR, Lines 22-32
            uav = self._recovery_target(k, deprecated, update)
            if uav is None:  # wait a round (lazy recovery): metadata or another CU's reply restores them
                msg = CuTrajectoryMessage(w, k, self._priorities(k, None), **self._repeat(own))
                self._own_last = msg
                return msg, CuStepReport(k, "wait", None, a_et, deprecated, update, answered=answered)
            msg = RecoveryRequest(w, k, self._priorities(k, None), uav)
            self._asked_now = uav
            self._donate_now = True
            self._own_last = msg
            return msg, CuStepReport(k, "request", uav, a_et, deprecated, update, answered=answered)
        uav = selected_uav(a_et, k, w, cfg.n_cus)  # Lines 14-15
        result, mode = None, "idle"
        if unified[uav] > 0 and len(self.trackers[uav].candidates) == 1:
            try:
                result = self._solve(k, uav, set(a_et))
                mode = "compute"
            except DmpcSolveError:
                mode = "failed"
        if result is None:
            msg = CuTrajectoryMessage(w, k, self._priorities(k, None), **self._repeat(own))
        else:
            msg = CuTrajectoryMessage(w, k, self._priorities(k, uav), uav, result.trajectory, **self._repeat(own))
        self._own_last = msg
        return msg, CuStepReport(k, mode, uav if mode != "idle" else None, a_et, deprecated, update, result, answered)

    def _repeat(self, own: object | None) -> dict[str, Any]:
        """The repeat fields of this round's message: last round's own trajectory (``repeat_trajectory``), else none."""
        if self.config.repeat_trajectory and isinstance(own, CuTrajectoryMessage) and own.uav_id is not None:
            return {"repeat_uav_id": own.uav_id, "repeat_trajectory": own.trajectory}
        return {}

    def _recovery_target(self, k: int, deprecated: tuple[int, ...], update: TrackerUpdate) -> int | None:
        """The deprecated UAV to request in round k, or None to wait a round (module docstring, step 5)."""
        w = self.cu_index
        if not self.config.lazy_recovery:
            return deprecated[(k + w) % len(deprecated)]
        open_ = [i for i in deprecated if i not in self._pending_replies]
        missing = [i for i in open_ if self.trackers[i].missing]
        if missing:
            return missing[(k + w) % len(missing)]
        fresh = set(update.newly_deprecated)
        if not open_ or all(i in fresh for i in open_):
            return None
        return open_[(k + w) % len(open_)]

    def _solve(self, k: int, uav: int, a_et: set[int]) -> MlrQpResult:
        """QP (13) for ``uav`` against every candidate of every other UAV (Alg. 1 Lines 17-18)."""
        cfg = self.config
        t_start = (k + 1) * cfg.round_s  # one round of latency (Eq. 13b)
        times = self.problem.check_times(t_start)
        pos, midway = [], []
        for j, entry in enumerate(self.trackers.entries):
            if j == uav:
                continue
            for cand in entry.candidates:
                pos.append(cand.positions_at(times))
                midway.append(j in a_et)  # Eq. 15: midway for j in A_ET(k), relaxed otherwise
        others = np.array(pos).reshape(-1, cfg.n_checks, 3)
        own = self.trackers[uav].candidates[0]
        target = self.targets_world[uav]
        return self.problem.solve(own, t_start, target, others, np.array(midway, bool),
                                  TrajectoryId(k, self.cu_index))

    def _deadlocked(self, firsts: Sequence[ReferenceTrajectory], k: int, dist: np.ndarray) -> np.ndarray:
        """(N,) bool: UAVs whose trajectory, computed within the last ``deadlock_rounds``
        rounds, holds them (motion < ``deadlock_motion_m``) away from their target.

        A recomputation of such a UAV would most likely return the same halt
        (DMPC-Swarm Appendix A, deadlock-aware triggering; the paper detects
        deadlock by Chen et al. 2024's condition, this is a cheaper proxy). A
        trajectory older than ``deadlock_rounds`` is not counted, so a held UAV
        is tried again as its neighbours move.
        """
        cfg = self.config
        t_now = k * cfg.round_s
        out = np.zeros(cfg.n_uavs, bool)
        for i, t in enumerate(firsts):
            calc = t.meta.calc_round
            if calc < self.first_round or k - calc > cfg.deadlock_rounds or dist[i] <= cfg.arrived_m:
                continue
            out[i] = planned_motion_m(t, max(t_now, t.t_start_s)) < cfg.deadlock_motion_m
        return out

    def _priorities(self, k: int, just_computed: int | None) -> np.ndarray:
        """J_{i,w}(k) (Appendix A) from the first candidate of each tracker, quantised; 0 for ``just_computed``."""
        cfg = self.config
        firsts = [e.candidates[0] for e in self.trackers.entries]
        calc = np.array([t.meta.calc_round for t in firsts], float)
        t_now = k * cfg.round_s
        pos = positions_at_each(firsts, np.array([max(t_now, t.t_start_s) for t in firsts]))
        dist = np.linalg.norm(self.targets_world - pos, axis=1)
        scale = {"rr": cfg.priority_scale_rr, "db": cfg.priority_scale_db_m, "ht": cfg.priority_scale_ht}[cfg.trigger]
        q = quantize(raw_priorities(cfg.trigger, k, calc, dist), scale)
        if cfg.deadlock_trigger:  # Appendix A: a deadlocked UAV gets priority 1
            q[self._deadlocked(firsts, k, dist)] = 1
        if just_computed is not None:
            q[just_computed] = 0  # Appendix A: just recomputed
        return q


def planned_motion_m(traj: ReferenceTrajectory, t_from_s: float) -> float:
    """Largest distance [m] of ``traj``'s positions from ``t_from_s`` on (its knots) from its position at ``t_from_s``."""
    times = np.r_[t_from_s, traj.t_start_s + traj.input_step_s * np.arange(1, traj.inputs.shape[0] + 1)]
    times = times[times >= t_from_s]
    p = traj.positions_at(times)
    return float(np.max(np.linalg.norm(p - p[0], axis=1)))


def summarize_reports(reports: Sequence[CuStepReport]) -> dict[str, Any]:
    """Counts and QP timings over CU rounds (one CU's or several; NaN timings when no QP was solved).

    Keys: ``rounds_with_mlr`` (distinct rounds in which a CU requested,
    donated or waited), ``deprecated_trackers`` (tracker deprecations summed),
    ``recovery_requests``, ``computations`` (rounds that solved a QP),
    ``qp_failures``, ``qp_solve_ms_median`` / ``qp_solve_ms_max`` (OSQP update +
    solve [ms]), ``qp_step_ms_median`` (build + solve [ms]), ``qp_iterations_median``;
    where the CU rounds went: ``cu_rounds`` (reports), ``cu_modes`` (mode ->
    CU rounds: ``compute``, ``idle``, ``failed`` planned or could not;
    ``request``, ``donate`` in recovery; ``wait`` waiting on a deprecated
    tracker), ``deprecations_by_cause`` (cause -> trackers, :class:`TrackerUpdate`'s
    ``causes``), ``rounds_all_deprecated`` (CU rounds in which a slot
    unaccounted for deprecated every tracker) and ``recovery_answered``
    (requests whose reply reached the requesting CU).
    """
    qps = [r.qp for r in reports if r.qp is not None]
    nan = float("nan")
    solve_ms = [q.solve_time_s * 1e3 for q in qps]
    step_ms = [(q.solve_time_s + q.build_time_s) * 1e3 for q in qps]
    modes = dict.fromkeys(("compute", "idle", "failed", "request", "donate", "wait"), 0)
    causes = dict.fromkeys(("slot", "suspect", "unnamed", "ambiguous", "crowded"), 0)
    for r in reports:
        modes[r.mode] += 1
        for cause, _ in r.tracker_update.causes:
            causes[cause] += 1
    return {
        "cu_rounds": len(reports),
        "cu_modes": modes,
        "deprecations_by_cause": causes,
        "rounds_all_deprecated": sum(r.tracker_update.all_deprecated for r in reports),
        "recovery_answered": sum(r.answered is True for r in reports),
        "rounds_with_mlr": len({r.round_index for r in reports if r.mode in ("request", "donate", "wait")}),
        "deprecated_trackers": sum(len(r.tracker_update.newly_deprecated) for r in reports),
        "recovery_requests": sum(r.mode == "request" for r in reports),
        "computations": len(qps),
        "qp_failures": sum(r.mode == "failed" for r in reports),
        "qp_solve_ms_median": float(np.median(solve_ms)) if qps else nan,
        "qp_solve_ms_max": float(np.max(solve_ms)) if qps else nan,
        "qp_step_ms_median": float(np.median(step_ms)) if qps else nan,
        "qp_iterations_median": float(np.median([q.iterations for q in qps])) if qps else nan,
    }
