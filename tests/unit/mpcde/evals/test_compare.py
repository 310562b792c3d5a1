"""compare: rows from a run's metrics, pooling over seeds, the table, and mode validation (no flight)."""

import numpy as np
import pytest

from mpcde.stacks import get_stack, stacks
from mpcde.errors import ConfigError
from mpcde.evals import compare as compare
from mpcde.evals.compare import (
    ROW_KEYS,
    SUMMARY_KEYS,
    check_modes,
    default_modes,
    format_table,
    row_from_metrics,
    run_compare,
    summarize,
)  # fmt: skip
from mpcde.flight.plots import min_inter_drone_distance


def fake_metrics(**changes):
    """A metrics dict shaped like mpcde.flight.metrics + loop extras (a perceiving, communicating run)."""
    m = {
        "success": True, "collisions": 0, "drone_drone_collisions": 0, "drone_obstacle_collisions": 0,
        "min_inter_drone_distance_m": 0.62, "min_obstacle_distance_m": None, "mission_time_s": 5.8,
        "arrived": 2, "n_drones": 2, "failed_drones": [], "path_length_m": 8.1, "mean_speed_mps": 1.2,
        "mean_accel_mps2": 0.4, "sim_time_s": 6.8, "wall_time_s": 34.0, "real_time_factor": 0.2,
        "radio": {"sent": 80, "delivered": 60, "lost": {"bernoulli": 15, "range": 5}},
        "tracking_pos_rmse_m": 0.07, "tracking_vel_rmse_mps": 0.23,
    }  # fmt: skip
    m.update(changes)
    return m


def test_a_row_has_exactly_the_row_keys_taken_from_the_metrics():
    row = row_from_metrics("comm", 3, fake_metrics())
    assert tuple(row) == ROW_KEYS
    assert row["planner_kind"] == get_stack("comm").kind and row["seed"] == 3
    assert row["min_distance_m"] == 0.62 and row["min_obstacle_clearance_m"] is None
    assert row["arrived"] == 2 and row["n_drones"] == 2 and row["mission_time_s"] == 5.8
    assert row["tracking_pos_rmse_m"] == 0.07 and row["tracking_vel_rmse_mps"] == 0.23


def test_radio_delivered_fraction_is_delivered_over_delivered_plus_all_losses():
    assert row_from_metrics("comm", 0, fake_metrics())["radio_delivered_fraction"] == pytest.approx(60 / 80)
    in_flight = fake_metrics(radio={"sent": 80, "delivered": 78, "lost": {}})  # 2 still in the air at the end
    assert row_from_metrics("comm", 0, in_flight)["radio_delivered_fraction"] == 1.0


def test_undefined_values_are_null_not_made_up():
    m = fake_metrics(mission_time_s=None, min_inter_drone_distance_m=None, real_time_factor=None,
                     radio={"sent": 0, "delivered": 0, "lost": {}}, success=False, arrived=1)  # fmt: skip
    del m["tracking_pos_rmse_m"], m["tracking_vel_rmse_mps"]  # no agent perceived
    row = row_from_metrics("placeholder", 0, m)
    for key in ("mission_time_s", "min_distance_m", "real_time_factor", "radio_delivered_fraction",
                "tracking_pos_rmse_m", "tracking_vel_rmse_mps"):  # fmt: skip
        assert row[key] is None, key
    table = format_table({"scenario": "s", "rows": [row], "summary": []})
    assert "placeholder" in table and "nan" not in table.lower() and "None" not in table


def test_summary_pools_two_seeds_per_mode():
    rows = [
        row_from_metrics("comm", 0, fake_metrics(mission_time_s=5.0, path_length_m=8.0,
                                                 min_inter_drone_distance_m=0.6)),
        row_from_metrics("comm", 1, fake_metrics(mission_time_s=None, success=False, path_length_m=10.0,
                                                 collisions=2, min_inter_drone_distance_m=0.1)),
        row_from_metrics("denied", 0, fake_metrics(mission_time_s=7.0)),
        row_from_metrics("denied", 1, fake_metrics(mission_time_s=9.0, min_inter_drone_distance_m=None)),
    ]  # fmt: skip
    comm, denied = summarize(rows, ("comm", "denied"))
    assert tuple(comm) == SUMMARY_KEYS
    assert comm["runs"] == 2 and comm["success_rate"] == 0.5 and comm["collisions"] == 2
    assert comm["min_distance_m"] == 0.1 and comm["path_length_m"] == pytest.approx(9.0)
    assert comm["mission_time_s"] == 5.0 and comm["mission_time_runs"] == 1  # only where defined
    assert denied["success_rate"] == 1.0 and denied["mission_time_s"] == pytest.approx(8.0)
    assert denied["mission_time_runs"] == 2 and denied["min_distance_m"] == 0.62
    table = format_table({"scenario": "s", "rows": rows, "summary": [comm, denied]})
    assert "pooled over seeds" in table and len(table.splitlines()) == 3 + 4 + 4 + 2


def test_min_inter_drone_distance_is_the_closest_pair_at_each_sample():
    pos = np.zeros((2, 3, 3))
    pos[0] = [[0, 0, 1], [3, 0, 1], [0, 4, 1]]
    pos[1] = [[0, 0, 1], [0.5, 0, 1], [0, 4, 1]]
    np.testing.assert_allclose(min_inter_drone_distance(pos), [3.0, 0.5])


def test_the_default_modes_are_comm_denied_auto():
    assert default_modes() == ("comm", "denied", "auto") and check_modes(["auto", "comm"]) == ("auto", "comm")


@pytest.mark.parametrize(
    "modes, value",
    [(["magic"], "magic"), (["comm", "magic"], "magic"), (["comm", "comm"], ["comm", "comm"]), ([], [])],
)
def test_unknown_repeated_or_no_modes_are_one_line_config_errors_naming_the_allowed(modes, value):
    with pytest.raises(ConfigError) as e:
        check_modes(modes)
    assert e.value.field == "--modes" and e.value.value == value
    assert all(s.name in e.value.allowed for s in stacks()) and "\n" not in str(e.value)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"modes": ("comm", "teleport")}, "--modes"),
        ({"seeds": ()}, "seeds"),
        ({"seeds": (0, 0)}, "seeds"),
        ({"seeds": (-1,)}, "seeds"),
        ({"duration_s": 0.0}, "duration_s"),
        ({"scenario": "no_such_scenario"}, "scenario"),
        ({"jobs": 0}, "jobs"),
        ({"jobs": 1.5}, "jobs"),
    ],
)
def test_bad_input_raises_before_anything_is_written(tmp_path, kwargs, field):
    out = tmp_path / "cmp"
    args = {"scenario": "crossing", "modes": ("placeholder",), "progress": False, **kwargs}
    with pytest.raises(ConfigError) as e:
        run_compare(out, **args)
    assert e.value.field == field
    assert list(tmp_path.iterdir()) == []


def test_a_non_empty_out_dir_is_refused_without_overwrite(tmp_path):
    (tmp_path / "keep.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not empty"):
        run_compare(tmp_path, "crossing", modes=("placeholder",), progress=False)
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_progress_prints_one_line_per_flight(tmp_path, capsys):
    # the progress line formats its numbers with text_table.cell; a loop variable of that name once shadowed it,
    # and every `mpcde compare` without --quiet died after its first flight
    run_compare(tmp_path / "cmp", "crossing", modes=("placeholder",), seeds=(0,), duration_s=0.5, progress=True)
    lines = [ln for ln in capsys.readouterr().out.splitlines() if ln.startswith("placeholder seed 0:")]
    assert len(lines) == 1 and "min_distance=" in lines[0] and "mission_time=" in lines[0], lines


def test_parallel_jobs_share_the_cores_only_where_render_workers_is_automatic(monkeypatch):
    from mpcde.config.scenario import load_scenario
    from mpcde.evals.compare import _share_cores
    from mpcde.flight.loop import prepare_run

    monkeypatch.setattr("os.cpu_count", lambda: 8)
    auto = prepare_run(load_scenario("crossing"))
    assert auto.config.run.render_workers == -1
    assert _share_cores(auto, 2).config.run.render_workers == 4
    assert _share_cores(auto, 3).config.run.render_workers == 2
    assert _share_cores(auto, 16).config.run.render_workers == 1  # never 0 (0 renders in the flight's process)
    monkeypatch.setattr("os.cpu_count", lambda: 64)
    assert _share_cores(auto, 2).config.run.render_workers == 16  # the field's limit
    fixed = prepare_run(load_scenario("crossing", {"run": {"render_workers": 0}}))
    assert _share_cores(fixed, 4) is fixed  # an explicit setting is the user's
