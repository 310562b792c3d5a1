"""Benchmark: one MLR-DMPC compute-unit step for N = 16 (DMPC-Swarm Alg. 1), with same-run baselines.

State: the 16-UAV circle swap of ``mpcde.evals.mlr`` (3 CUs, ideal messages,
in-process) flown for 12 rounds (2.4 s, the UAVs in motion toward the
centre); then CU 0's trackers and the next inbox are frozen. Timed with
:func:`timing.median_ms` (OMP_NUM_THREADS=1):

* Alg. 2 tracker update (16 trackers, 16 state messages, 3 CU messages);
* trigger: HT priorities, zero-rule consensus (Eq. 11), A_ET and selection;
* QP (13) build + OSQP solve for the selected UAV, in three sizes:
  every other tracker with ONE candidate (15 x 15 BVC rows, the baseline:
  no recomputation to resolve), with TWO candidates for 3 UAVs (what follows
  a round in which 3 CUs recomputed: 18 x 15 rows), and with two for all 15
  (30 x 15, the size the pattern is built for; the second candidate of each
  is its trajectory delayed by one round);
* the CU step = update + trigger + QP (typical size);
* against our existing per-drone DMPC QP, :class:`planners.dmpc.DmpcProblem`
  in ``bvc`` mode (triple integrator, K = 15, h = 0.2 s, terminal halt, 15
  neighbour slots, the same OSQP tolerance 1e-3) on the same states and neighbours.

Ratios are against the one-candidate QP (message loss's cost) and against
DmpcProblem. Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_mlr.py``.
"""

from __future__ import annotations

import argparse

import numpy as np
from timing import median_ms

from mpcde.evals.mlr import circle_swap
from planners.dmpc.config import DmpcConfig
from planners.dmpc.mlr.compute_unit import ComputeUnit
from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.tracker import InformationTrackers
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId
from planners.dmpc.mlr.trigger import consensus, event_set, selected_uav
from planners.dmpc.mlr.types import CuTrajectoryMessage, RecoveryRequest, UavStateMessage
from planners.dmpc.mlr.uav import Uav
from planners.dmpc.qp import DmpcProblem
from planners.dmpc.types import DmpcPlan


def frozen_state(rounds: int = 12):
    """Fly the swap in process for ``rounds`` rounds; returns (config, CUs, the next round's inbox of CU 0, k)."""
    cfg = MlrConfig(n_uavs=16, n_cus=3)
    start, goal = circle_swap()
    initial = [ReferenceTrajectory.hover(TrajectoryId(-1, -1), 0.0, p, cfg.n_inputs, cfg.input_step_s) for p in start]
    uavs = [Uav(i, initial[i], goal[i]) for i in range(16)]
    cus = [ComputeUnit(cfg, w, initial, goal) for w in range(3)]
    inbox: list = []
    for k in range(rounds):
        sent = []
        for i, u in enumerate(uavs):
            out, _ = u.step(k, inbox, u.reference.positions_at(np.array([k * cfg.round_s]))[0], np.zeros(3))
            sent += out
        for cu in cus:
            msg, _ = cu.step(k, [m for m in inbox if getattr(m, "cu_id", None) != cu.cu_index])
            if msg is not None:
                sent.append(msg)
        inbox = sent
    return cfg, cus, inbox, rounds


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    repeats = 30
    cfg, cus, inbox, k = frozen_state()
    cu = cus[0]
    cu_inbox = [m for m in inbox if getattr(m, "cu_id", None) != 0]
    states = {m.uav_id: m for m in cu_inbox if isinstance(m, UavStateMessage)}
    cu_msgs = [m for m in cu_inbox if isinstance(m, (CuTrajectoryMessage, RecoveryRequest))]
    new = {m.uav_id: m.trajectory for m in cu_msgs if isinstance(m, CuTrajectoryMessage) and m.uav_id is not None}
    entries0 = list(cu.trackers.entries)

    def update() -> InformationTrackers:
        tr = InformationTrackers([e.candidates[0] for e in entries0])
        tr.entries = list(entries0)
        tr.update({i: m.following for i, m in states.items()}, new, {}, True)
        return tr

    trackers = update()

    def trigger() -> int:
        unified = consensus([m.priorities for m in cu_msgs] + [cu._priorities(k, None)], cfg.n_uavs)
        return selected_uav(event_set(unified, cfg.n_cus), k, 0, cfg.n_cus)

    uav = trigger()
    while len(trackers[uav].candidates) != 1:
        uav = (uav + 1) % cfg.n_uavs
    t0 = (k + 1) * cfg.round_s
    times = cu.problem.check_times(t0)
    own = trackers[uav].candidates[0]
    target = cu.targets_world[uav]
    firsts = [(j, trackers[j].candidates[0]) for j in range(cfg.n_uavs) if j != uav]
    one = np.array([c.positions_at(times) for _, c in firsts])
    delayed = np.array([c.positions_at(np.maximum(times - cfg.round_s, c.t_start_s)) for _, c in firsts])
    sizes = {"1 candidate each (15x15 rows)": one,
             "2 candidates for 3 UAVs (18x15)": np.concatenate([one, delayed[:3]]),
             "2 candidates for all 15 (30x15)": np.concatenate([one, delayed])}
    a_et = set(event_set(consensus([m.priorities for m in cu_msgs], cfg.n_uavs), cfg.n_cus))
    mid_one = np.array([j in a_et for j, _ in firsts])

    def qp(others: np.ndarray):
        mid = np.concatenate([mid_one, mid_one[: others.shape[0] - 15]])
        return cu.problem.solve(own, t0, target, others, mid, TrajectoryId(k, 0))

    t_update = median_ms(update, repeats)
    t_trigger = median_ms(trigger, repeats)
    print(f"MLR-DMPC CU step, N = 16, M = 3, round {k} of the swap, UAV {uav}, median of {repeats} [ms]")
    print(f"  tracker update (Alg. 2)          {t_update:8.3f}")
    print(f"  trigger (App. A, Eq. 11)         {t_trigger:8.3f}")
    qp_ms = {}
    for name, others in sizes.items():
        qp_ms[name] = median_ms(lambda o=others: qp(o), repeats)
        res = qp(others)
        print(f"  QP build + solve, {name:32s} {qp_ms[name]:8.3f}   ({res.iterations} OSQP iterations)")
    typical = "2 candidates for 3 UAVs (18x15)"
    step = t_update + t_trigger + qp_ms[typical]
    print(f"  CU step (update + trigger + QP, typical size) {step:8.3f}")
    base = qp_ms["1 candidate each (15x15 rows)"]
    for name in sizes:
        print(f"  ratio QP {name} / 1 candidate each: {qp_ms[name] / base:5.2f}")

    # Baseline: planners.dmpc.DmpcProblem in BVC mode on the same states.
    # DmpcConfig's OSQP tolerances are class constants: a subclass solves it to MLR's
    at_mlr_tolerances = type("DmpcAtMlrTolerances", (DmpcConfig,), {"osqp_eps_abs": cfg.osqp_eps_abs, "osqp_eps_rel": cfg.osqp_eps_rel})
    dcfg = at_mlr_tolerances(model="triple", collision_mode="bvc", horizon_steps=15, step_s=0.2, terminal_halt=True,
                             max_neighbours=15, r_min_m=cfg.d_hat_min_m, downwash=cfg.downwash, limits=cfg.limits,
                             pos_min_world=cfg.pos_min_world,
                             pos_max_world=cfg.pos_max_world)
    problem = DmpcProblem(dcfg)
    grid = t0 + 0.2 * np.arange(16)

    def plan(tr: ReferenceTrajectory) -> DmpcPlan:
        x = tr.states_at(grid)
        return DmpcPlan(t0, 0.2, x[:, :3], x[:, 3:6], x[:, 6:9])

    neighbours = [plan(c).as_neighbor_prediction(j, t0) for j, c in firsts]
    own_plan, x0 = plan(own), own.states_at(np.array([t0]))[0]

    def dmpc():
        return problem.solve(x0, target, neighbours, own_plan, t_now_s=t0)

    t_dmpc = median_ms(dmpc, repeats)
    print(f"  baseline DmpcProblem bvc (15 neighbours x 15 steps) {t_dmpc:8.3f}   ({dmpc().iterations} iterations)")
    print(f"  ratio MLR QP (1 candidate each) / DmpcProblem bvc: {base / t_dmpc:5.2f}")
    print(f"  ratio MLR CU step (typical) / DmpcProblem bvc: {step / t_dmpc:5.2f}")


if __name__ == "__main__":
    main()
