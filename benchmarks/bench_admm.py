"""Benchmark: formation DMPC by decentralized ADMM (Stomberg et al.), the analogue of the paper's Tables 2-3.

Scenarios: N drones start scattered (uniform in 4 m x 4 m x 1 m around
(0, 0, 2) m, at rest) and fly a horizontal polygon formation (circumradius
1 m) whose centre moves along +x at 0.5 m/s; graphs: 4 drones on a ring, 4 on
the complete graph, 8 on a ring. Kinematic closed loop (double integrator,
the applied input is ``AdmmStepResult.input_now``), 50 MPC steps of h = 0.2 s
per seed, default :class:`planners.dmpc.admm.config.AdmmFormationConfig`
(l_max = 5, rho = 1, warm start, Remark 1).

Printed per scenario:

* ADMM time per MPC step and drone (that drone's Step 3 plus its Steps 4-8
  bookkeeping, no network: in-process message passing), per ADMM iteration,
  and per Step 3 (local QP: q update + OSQP solve) and Steps 4-8 (messages,
  average, zbar, multiplier update): median and max over drones x steps,
  like the paper's Table 2; then the share of Step 3 in each drone's ADMM
  time (Table 3); and the driver's wall time for the whole round with all N
  drones run one after another in one process.
* Baseline, measured in the same run at every 5th state of the closed loop
  with :func:`timing.median_ms`: the centralized QP of the same OCP (same
  states, references and u(t)), built and set up once per flight
  (:class:`CentralizedFormationQp`; the one-off build is printed apart), per
  step q and bounds updated and solved by OSQP at the local QPs' tolerance
  (``osqp_eps_abs``, 1e-4), cold and warm-started from the previous step's
  centralized solution shifted by one step. Ratio = centralized / ADMM per
  drone (what one drone computes) and centralized / whole round (all N
  drones in turn).
* Quality of 5 warm-started iterations: at every step the centralized optimum
  (OSQP eps 1e-9, polished) from the same state: cost gap
  (J(ADMM plans) - J*) / J* and max |u - u*| over the drones for the decided
  input (u[1], applied at t + h with Remark 1) and over the whole plan;
  all steps and from t = 2 s on (the paper reports its residual after "an
  initialization phase of a few seconds"). Plus the formation error chi at
  2 s, 4 s and 10 s and the largest |v|, |u| flown. A cold-started variant
  (``warm_start=False``) shows what the warm start buys.

``--sweep`` adds the settings sweep behind the defaults (4 ring, same seeds):
the ADMM penalty rho in {0.1, 0.3, 1, 3, 10, 100} (the paper tuned it in
{0.1, 1, 10, 100}) and OSQP's own step size, adaptive step and tolerance
for the local QPs: OSQP iterations, local QP time and the distance to the
optimum per setting.

Run: ``OMP_NUM_THREADS=1 .venv/bin/python benchmarks/bench_admm.py [--seeds 3] [--sweep]``
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np
from timing import median_ms

from planners.dmpc.admm.centralized import CentralizedFormationQp, formation_cost
from planners.dmpc.admm.config import AdmmFormationConfig
from planners.dmpc.admm.formation import AdmmFormationAgent, solve_admm_round
from planners.dmpc.admm.ocp import DroneLayout, shift_decision, shift_dual
from planners.dmpc.formation_graph import FormationGraph, complete_edges, formation_error, polygon_slots, ring_edges
from planners.dmpc.model import discrete_model

SPEED_M_S = 0.5
STEPS = 50
BASELINE_EVERY = 5
SCENARIOS = {"4 ring": (4, ring_edges), "4 complete": (4, complete_edges), "8 ring": (8, ring_edges)}


def _references(graph: FormationGraph, cfg: AdmmFormationConfig, t_s: float) -> np.ndarray:
    """(N, K, 3) slot references of the moving centre at t + k h, k = 1..K."""
    k = np.arange(1, cfg.horizon_steps + 1)[:, None]
    centre = np.array([0.0, 0.0, 2.0]) + (t_s + k * cfg.step_s) * np.array([SPEED_M_S, 0.0, 0.0])
    return np.transpose(graph.references(centre), (1, 0, 2))


def _shift_central(primal: np.ndarray, dual: np.ndarray, K: int) -> tuple[np.ndarray, np.ndarray]:
    """The previous centralized solution one step on, per drone (warm start of the baseline)."""
    lay = DroneLayout(K)
    x = np.stack([shift_decision(p, lay, extrapolate_positions=True) for p in primal])
    y = np.stack([shift_dual(d, K) for d in dual])
    return x, y


def fly(cfg: AdmmFormationConfig, n: int, edges, seed: int, baseline: bool, on_results=None) -> dict:
    """One closed loop; per-step ADMM figures, baseline timings and the distance to the optimum."""
    graph = FormationGraph(polygon_slots(n, 1.0), edges(n))
    rng = np.random.default_rng(seed)
    x = np.zeros((n, 6))
    x[:, :3] = rng.uniform(-2.0, 2.0, (n, 3)) * [1.0, 1.0, 0.25] + [0.0, 0.0, 2.0]
    A, B = discrete_model("double", cfg.step_s)
    agents = [AdmmFormationAgent(i, cfg, graph.offsets_of(i)) for i in range(n)]
    K = cfg.horizon_steps
    reference = CentralizedFormationQp(cfg, graph, eps=1e-9, polish=True)
    central = CentralizedFormationQp(cfg, graph, eps=cfg.osqp_eps_abs, polish=False)  # the baseline
    out = {k: [] for k in ("step", "iter", "qp", "book", "share", "round", "osqp", "gap", "du_next", "du_plan",
                           "cold_ms", "warm_ms", "central_it", "chi")}  # fmt: skip
    inputs_now = np.zeros((n, 3))
    warm = None
    vmax = amax = 0.0
    for step in range(STEPS):
        t = step * cfg.step_s
        refs = _references(graph, cfg, t)
        for i, a in enumerate(agents):
            a.start_step(x[i], refs[i], t)
        t0 = time.perf_counter()
        results = solve_admm_round(agents)
        out["round"].append(time.perf_counter() - t0)
        if on_results is not None:
            on_results(results)
        for r in results:
            out["step"].append(r.admm_time_s)
            out["iter"].extend(r.qp_solve_s + r.bookkeeping_s)
            out["qp"].extend(r.qp_solve_s)
            out["book"].extend(r.bookkeeping_s)
            out["share"].append(np.sum(r.qp_solve_s) / r.admm_time_s)
            out["osqp"].extend(r.osqp_iterations)
        u_now = inputs_now if cfg.delay_compensation else None
        best = reference.solve(x, refs, u_now)
        acc = np.stack([r.acc_world for r in results])
        pos = np.stack([r.pos_world for r in results])
        cost = formation_cost(cfg, graph, refs, pos, acc, np.array([r.slack for r in results]))
        out["gap"].append((cost - best.cost) / best.cost)
        decided = 1 if cfg.delay_compensation else 0
        out["du_next"].append(np.abs(acc[:, decided] - best.acc_world[:, decided]).max())
        out["du_plan"].append(np.abs(acc - best.acc_world).max())
        if baseline:
            ws = None if warm is None else _shift_central(warm.primal, warm.dual, K)
            if step % BASELINE_EVERY == 0:
                out["cold_ms"].append(median_ms(lambda: central.solve(x, refs, u_now), 5))
                out["warm_ms"].append(median_ms(lambda: central.solve(x, refs, u_now, warm_start=ws), 5))
            warm = central.solve(x, refs, u_now, warm_start=ws)
            out["central_it"].append(warm.iterations)
        u = np.stack([r.input_now for r in results])
        inputs_now = np.stack([r.input_next for r in results])
        x = x @ A.T + u @ B.T  # x(t + h) = A x(t) + B u(t)
        vmax, amax = max(vmax, np.abs(x[:, 3:]).max()), max(amax, np.abs(u).max())
        out["chi"].append(formation_error(x[:, :3], graph))  # at t + h
    out = {k: np.asarray(v) for k, v in out.items()}
    out["vmax"], out["amax"] = vmax, amax
    out["per_drone_share"] = out["share"].reshape(STEPS, n).mean(axis=0)
    return out


def _pool(runs: list[dict], key: str) -> np.ndarray:
    return np.concatenate([r[key].ravel() for r in runs])


def _sweep(cfg: AdmmFormationConfig, seeds: int) -> None:
    """The closed loop of "4 ring" under other settings (module docstring, ``--sweep``)."""
    print()
    print("Settings sweep, 4 ring, default marked *; |du| of the decided input [m/s^2]; refac: OSQP")
    print("refactorisations (adaptive step); max-it: local QPs stopped at osqp_max_iter")
    head = (f"{'setting':<20} {'OSQP it med/p95/max':>19} {'QP ms med/mean/max':>19} {'|du| med':>8} "
            f"{'t>=2s max':>9} {'gap% med':>8} {'refac':>5} {'max-it':>6}")  # fmt: skip
    print(head)
    print("-" * len(head))
    variants = [(f"rho = {r:g}", {"rho": r}) for r in (0.1, 0.3, 1.0, 3.0, 10.0, 100.0)]
    variants += [
        ("OSQP rho = 0.1", {"osqp_rho": 0.1}),
        ("OSQP rho = 3", {"osqp_rho": 3.0}),
        ("OSQP adaptive rho", {"osqp_adaptive_rho": True}),
        ("OSQP eps = 1e-5", {"osqp_eps_abs": 1e-5, "osqp_eps_rel": 1e-5}),
        ("OSQP eps = 1e-6", {"osqp_eps_abs": 1e-6, "osqp_eps_rel": 1e-6}),
    ]
    skip = int(round(2.0 / cfg.step_s))
    for label, change in variants:
        c = replace(cfg, **change)
        counts = {"refactor": 0, "max_it": 0}

        def count(results, counts=counts) -> None:
            counts["refactor"] += sum(r.osqp_rho_updates for r in results)
            counts["max_it"] += sum(r.osqp_max_iter_hits for r in results)

        rs = [fly(c, 4, ring_edges, seed, False, on_results=count) for seed in range(seeds)]
        it, qp = _pool(rs, "osqp"), _pool(rs, "qp") * 1e3
        du, gap = np.stack([r["du_next"] for r in rs]), _pool(rs, "gap") * 100
        star = "*" if c == cfg else " "
        its = f"{int(np.median(it))}/{int(np.percentile(it, 95))}/{it.max()}"
        qps = f"{np.median(qp):.3f}/{qp.mean():.3f}/{qp.max():.2f}"
        print(f"{star}{label:<19} {its:>19} {qps:>19} {np.median(du):>8.1e} {du[:, skip:].max():>9.1e} "
              f"{np.median(gap):>8.3f} {counts['refactor']:>5} {counts['max_it']:>6}")  # fmt: skip


def _med_max(values: np.ndarray) -> str:
    return f"{np.median(values):.3f}/{values.max():.2f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3, help="closed loops per scenario")
    parser.add_argument("--sweep", action="store_true", help="also sweep rho and the local OSQP settings")
    args = parser.parse_args()
    cfg = AdmmFormationConfig()
    fly(cfg, 4, ring_edges, 999, baseline=True)  # warm-up (imports, caches)
    t_start = time.perf_counter()
    runs = {name: [fly(cfg, n, e, seed, True) for seed in range(args.seeds)] for name, (n, e) in SCENARIOS.items()}
    cold_cfg = replace(cfg, warm_start=False)
    cold = [fly(cold_cfg, 4, ring_edges, seed, False) for seed in range(args.seeds)]
    print(f"formation ADMM, l_max = {cfg.l_max}, rho = {cfg.rho}, K = {cfg.horizon_steps}, h = {cfg.step_s} s; "
          f"{args.seeds} seeds x {STEPS} steps per scenario, {time.perf_counter() - t_start:.1f} s")  # fmt: skip
    print()
    print("Table 2 analogue, per drone, times in ms as median/max over drones x steps (or x iterations);")
    print("share: Step 3 / drone's ADMM time; round: whole round, all N drones in turn in one process")
    head = (f"{'scenario':<10} {'ADMM/step':>12} {'per iter':>11} {'Step 3 QP':>11} {'Steps 4-8':>11} "
            f"{'share':>5} {'round':>6} {'OSQP it med/p95/max':>19}")  # fmt: skip
    print(head)
    print("-" * len(head))
    admm_med, round_med = {}, {}
    for name, rs in runs.items():
        cols = [_med_max(_pool(rs, key) * 1e3) for key in ("step", "iter", "qp", "book")]
        rnd, it = _pool(rs, "round") * 1e3, _pool(rs, "osqp")
        admm_med[name], round_med[name] = np.median(_pool(rs, "step")) * 1e3, np.median(rnd)
        its = f"{int(np.median(it))}/{int(np.percentile(it, 95))}/{it.max()}"
        print(f"{name:<10} {cols[0]:>12} {cols[1]:>11} {cols[2]:>11} {cols[3]:>11} "
              f"{np.mean(_pool(rs, 'share')) * 100:>4.0f}% {np.median(rnd):>6.2f} {its:>19}")  # fmt: skip
    shares = np.mean([r["per_drone_share"] for r in runs["4 ring"]], axis=0)
    print("Table 3 analogue (4 ring), Step 3 share per drone: "
          + ", ".join(f"{i}: {s * 100:.0f}%" for i, s in enumerate(shares)))  # fmt: skip
    print()
    print(f"Baseline: centralized QP of the same OCP, built once, per step q and bounds updated, OSQP eps "
          f"{cfg.osqp_eps_abs:g};")  # fmt: skip
    print(f"median of 5 repeats at every {BASELINE_EVERY}th state, median over states; ratios: warm-started "
          "centralized / ADMM")  # fmt: skip
    head = (f"{'scenario':<10} {'cold ms':>7} {'warm ms':>7} {'OSQP it med/max':>15} {'build ms':>8} "
            f"{'/ ADMM per drone':>16} {'/ ADMM round':>12}")  # fmt: skip
    print(head)
    print("-" * len(head))
    for name, rs in runs.items():
        n, edges = SCENARIOS[name]
        graph = FormationGraph(polygon_slots(n, 1.0), edges(n))
        build = median_ms(lambda: CentralizedFormationQp(cfg, graph, eps=cfg.osqp_eps_abs, polish=False), 5)
        c, w = np.median(_pool(rs, "cold_ms")), np.median(_pool(rs, "warm_ms"))
        it = _pool(rs, "central_it")
        print(f"{name:<10} {c:>7.2f} {w:>7.2f} {f'{int(np.median(it))}/{it.max()}':>15} {build:>8.2f} "
              f"{w / admm_med[name]:>15.2f}x {w / round_med[name]:>11.2f}x")  # fmt: skip
    print()
    print("Distance of 5 warm-started iterations to the centralized optimum (eps 1e-9), closed loop;")
    print("gap = (J_admm - J*) / J* in %; du = max over drones |u - u*| of the decided input u[1] [m/s^2];")
    print("late = from t = 2 s on; plan = max |du| over whole plans; chi [m] at 2 s / 4 s / 10 s, max over seeds")
    head = (f"{'scenario':<12} {'gap% med/p95/max':>16} {'late':>5} {'du med/p95/max':>20} {'late':>7} "
            f"{'plan':>4} {'chi 2s/4s/10s':>20} {'|v|max':>6} {'|u|max':>6}")  # fmt: skip
    print(head)
    print("-" * len(head))
    skip = int(round(2.0 / cfg.step_s))
    for name, rs in list(runs.items()) + [("4 ring cold", cold)]:
        gap = np.stack([r["gap"] for r in rs]) * 100
        du = np.stack([r["du_next"] for r in rs])
        chi = np.stack([r["chi"] for r in rs])
        gaps = f"{np.median(gap):.2f}/{np.percentile(gap, 95):.1f}/{gap.max():.0f}"
        dus = f"{np.median(du):.0e}/{np.percentile(du, 95):.1f}/{du.max():.1f}"
        chis = f"{chi[:, skip - 1].max():.3f}/{chi[:, 2 * skip - 1].max():.0e}/{chi[:, -1].max():.0e}"
        print(f"{name:<12} {gaps:>16} {gap[:, skip:].max():>5.2f} {dus:>20} {du[:, skip:].max():>7.1e} "
              f"{max(r['du_plan'].max() for r in rs):>4.1f} {chis:>20} {max(r['vmax'] for r in rs):>6.3f} "
              f"{max(r['amax'] for r in rs):>6.3f}")  # fmt: skip
    print("4 ring cold: warm_start=False (every step from gamma = 0 and the free response)")
    print("paper, Table 2 (C++, qpOASES, LCM): ADMM per step median 6.61 ms, per iteration 0.98 ms,")
    print("Step 3 0.09 ms; Table 3: Step 3 share 15-37 %; Fig. 6: |u - u*| < 2e-2 m/s after the start-up")
    if args.sweep:
        _sweep(cfg, args.seeds)


if __name__ == "__main__":
    main()
