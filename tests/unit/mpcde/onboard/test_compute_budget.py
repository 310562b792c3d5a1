"""Per-component compute time: totals, calls, per-call and per-simulated-second figures, 'other'."""

from __future__ import annotations

import pytest

from mpcde.onboard.budget import ComputeBudget


def test_result_books_totals_calls_and_rates() -> None:
    b = ComputeBudget()
    b.add("map_insert", 0.3, 3)
    b.add("map_insert", 0.1)
    b.add("render", 2.0, 40)
    with b.measure("yaw"):
        pass
    r = b.result(sim_time_s=2.0, main_wall_s=1.0)
    assert r["map_insert"] == {"total_s": 0.4, "calls": 4, "ms_per_call": 100.0, "ms_per_sim_s": 200.0}
    assert r["render"]["ms_per_call"] == pytest.approx(50.0)
    assert r["yaw"]["calls"] == 1 and r["yaw"]["total_s"] < 0.01
    # 'other': main-process wall time less the main-process components (render runs in the workers)
    assert r["other"]["total_s"] == pytest.approx(1.0 - 0.4 - r["yaw"]["total_s"], abs=1e-4)
    assert list(r)[0] == "render"  # largest first


def test_top_names_the_largest_components() -> None:
    b = ComputeBudget()
    for name, s in [("a", 1.0), ("b", 3.0), ("c", 2.0), ("d", 0.5)]:
        b.add(name, s, 2)
    line = ComputeBudget.top(b.result(10.0), 3)
    assert line.startswith("b 3.0 s (1500.00 ms x 2), c 2.0 s") and "d " not in line
