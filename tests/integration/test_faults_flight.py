"""The built-in ``faults`` scenario flies to its end with every fault on, and its metrics report each one."""

from __future__ import annotations

import pytest

import mpcde

pytestmark = pytest.mark.slow


def test_the_faults_scenario_survives_and_reports_every_fault():
    m = mpcde.fly("faults", duration_s=15.0).metrics  # drone 5 fails at 8 s, the radio is jammed 6-9 s
    assert m["sim_time_s"] == pytest.approx(15.0, abs=0.01)  # flew to the end
    f = m["faults"]
    assert f["frames_dropped"] > f["frames_dropped_in_windows"] > 0  # random bursts and drone 2's window (4-7 s)
    assert f["frames_dropped_per_drone"][2] >= f["frames_dropped_in_windows"] >= 70  # 3 s at 25 Hz
    assert f["detections_removed"] > 0 and f["false_positives_added"] > 0
    assert f["drone_failures"] == [{"drone": 5, "time_s": pytest.approx(8.0, abs=0.005), "scheduled_s": 8.0}]
    assert 5 in m["failed_drones"]
    assert f["invalid_depth_fraction"] > 0.02  # the 2 % holes plus what lies out of range
    assert f["pose_error_mean_m"] > 0 and f["pose_error_max_m"] >= f["pose_error_final_m"] > 0
    r = m["radio"]
    assert r["loss_model"] == "gilbert_elliott" and r["lost"]["loss"] > 0 and r["lost"]["jamming"] > 0
    assert r["delay_s"] == 0.1 and r["mean_latency_s"] == pytest.approx(0.1, abs=1e-9)
