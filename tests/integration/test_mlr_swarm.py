"""The kinematic MLR-DMPC swarm (DMPC-Swarm Sec. 5.3-5.4) over the simulated radio."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from mpcde.evals.mlr import circle_swap, format_table, formation_points, run_eval_mlr
from mpcde.evals.mlr_swarm import MlrSwarmConfig, run_mlr_swarm
from planners.dmpc.collision import ellipsoidal_distance
from planners.dmpc.mlr.config import MlrConfig
from sim.radio import RadioConfig

SWAP16 = MlrSwarmConfig(mlr=MlrConfig(n_uavs=16, n_cus=3), duration_s=40.0)


def _small(**kw) -> MlrSwarmConfig:
    return MlrSwarmConfig(mlr=MlrConfig(n_uavs=6, n_cus=2), duration_s=12.0, **kw)


@pytest.mark.slow
def test_ideal_radio_16_uav_swap_arrives_without_collision() -> None:
    start, goal = circle_swap()
    res = run_mlr_swarm(SWAP16, start, [goal])
    assert res.collisions == 0 and res.min_distance_m >= SWAP16.mlr.d_hat_min_m - 0.01
    assert np.isfinite(res.arrival_time_s)
    assert res.rounds_with_mlr == 0 and res.deprecated_trackers == 0 and res.qp_failures == 0
    # every CU round planned or had nothing to plan; no recovery, no UAV left at rest away from its goal
    assert res.cu_rounds == 3 * res.rounds == sum(res.cu_modes.values())
    assert res.cu_modes["compute"] + res.cu_modes["idle"] == res.cu_rounds and res.rounds_all_deprecated == 0
    assert sum(res.deprecations_by_cause.values()) == 0 and res.halts_released == res.halts_begun


@pytest.mark.slow
def test_deaf_cus_mlr_dmpc_stays_safe_while_the_ignore_loss_baseline_jumps_references() -> None:
    """Fig. 4: CUs deaf for the first 2 s. On this test's seed the baseline also collides."""
    start, goal = circle_swap()
    deaf = dataclasses.replace(SWAP16, cu_deaf_windows_s=((0.0, 2.0),))
    mlr = run_mlr_swarm(deaf, start, [goal])
    assert mlr.collisions == 0 and mlr.min_distance_m >= deaf.mlr.d_hat_min_m - 0.01
    assert mlr.rounds_with_mlr >= 8 and mlr.recovery_requests > 0 and mlr.cu_deaf_drops > 0
    assert mlr.max_reference_jump_m == 0.0  # every switch continuous: Assumption 1 holds
    assert np.isfinite(mlr.arrival_time_s)
    base = run_mlr_swarm(dataclasses.replace(deaf, ignore_message_loss=True), start, [goal])
    assert base.rounds_with_mlr == 0 and base.deprecated_trackers == 0
    assert base.max_reference_jump_m > 0.1  # trajectories started from stale beliefs
    assert base.min_distance_m < mlr.min_distance_m


@pytest.mark.slow
def test_bernoulli_loss_of_25_percent_keeps_mlr_dmpc_collision_free() -> None:
    start, goal = circle_swap(jitter_m=0.05, seed=1)
    cfg = dataclasses.replace(SWAP16, seed=1, duration_s=20.0,
                              radio=RadioConfig(loss_model="bernoulli", loss_probability=0.25))
    res = run_mlr_swarm(cfg, start, [goal])
    assert res.collisions == 0 and res.min_distance_m >= cfg.mlr.d_hat_min_m - 0.01
    assert res.recovery_requests > 0 and res.max_reference_jump_m == 0.0


def test_gilbert_elliott_loss_on_a_small_swarm_is_collision_free_and_reproducible() -> None:
    start, goal = circle_swap(n=6, radius_m=1.5, jitter_m=0.05, seed=3)
    cfg = _small(seed=3, radio=RadioConfig(loss_model="gilbert_elliott", ge_p_good_to_bad=0.1,
                                           ge_p_bad_to_good=0.3, ge_loss_bad=0.9))
    a = run_mlr_swarm(cfg, start, [goal])
    b = run_mlr_swarm(cfg, start, [goal])
    assert a.collisions == 0 and a.radio["lost"].get("loss", 0) > 0
    ma, mb = a.metrics(), b.metrics()
    for m in (ma, mb):
        for key in ("qp_solve_ms_median", "qp_solve_ms_max", "qp_step_ms_median"):
            m.pop(key)  # timings differ run to run; everything else is identical
    assert json.dumps(ma, sort_keys=True) == json.dumps(mb, sort_keys=True)  # (NaN-safe)
    np.testing.assert_array_equal(a.positions_world, b.positions_world)


def test_collisions_are_measured_between_round_boundaries() -> None:
    """Two UAVs whose targets are each other's starts, with d̂ far below d_min: a collision is found."""
    start = np.array([[-1.0, 0.0, 1.2], [1.0, 0.0, 1.2], [0.0, 2.5, 1.2]])
    goal = np.array([[1.0, 0.0, 1.2], [-1.0, 0.0, 1.2], [0.0, 2.5, 1.2]])
    cfg = MlrSwarmConfig(mlr=MlrConfig(n_uavs=3, n_cus=2, d_hat_min_m=0.01), duration_s=6.0,
                         collision_distance_m=0.3)
    res = run_mlr_swarm(cfg, start, [goal])
    assert res.collisions == 1 and res.collision_pairs[0][:2] == (0, 1)
    d_bound = ellipsoidal_distance(res.positions_world[:, 0] - res.positions_world[:, 1], cfg.mlr.downwash)
    assert res.min_distance_m <= d_bound.min() + 1e-12


def test_invalid_swarm_fields_are_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match=r"^calc_s=0.2: calc_s \+ radio.delay_s < round_s=0.2$"):
        MlrSwarmConfig(calc_s=0.2)
    with pytest.raises(ValueError, match=r"^cu_deaf_windows_s=\(\(2.0, 1.0\),\): pairs"):
        MlrSwarmConfig(cu_deaf_windows_s=((2.0, 1.0),))
    with pytest.raises(ValueError, match=r"^disturbance_m=-0.1: a finite number >= 0$"):
        MlrSwarmConfig(disturbance_m=-0.1)
    with pytest.raises(ValueError, match="seeds=0"):
        run_eval_mlr(__import__("pathlib").Path("/nonexistent"), seeds=0)


def test_formations_keep_the_planning_distance_between_targets() -> None:
    for name in ("plane", "pyramid", "cube", "sphere"):
        p = formation_points(name)
        iu = np.triu_indices(16, 1)
        assert ellipsoidal_distance(p[iu[0]] - p[iu[1]], 1.5).min() > MlrConfig().d_hat_min_m + 0.05
        cfg = MlrConfig()
        assert np.all(p >= np.array(cfg.pos_min_world)) and np.all(p <= np.array(cfg.pos_max_world))


@pytest.mark.slow
def test_eval_writes_rows_and_a_table(tmp_path) -> None:
    res = run_eval_mlr(tmp_path, experiments=("fig3c_triggers",), formation_duration_s=60.0)
    saved = json.loads((tmp_path / "results.json").read_text())
    assert [r["variant"] for r in saved["rows"]] == ["rr", "db", "ht"]
    assert (tmp_path / "table.md").read_text().strip() == format_table(res).strip()
    assert all(r["collisions"] == 0 for r in saved["rows"])
