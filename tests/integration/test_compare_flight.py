"""compare flies the crossing pair blind and with DMPC, paired by seed, and the physics tells them apart."""

import json
import time

import numpy as np
import pytest

from mpcde.evals.compare import ROW_KEYS, run_compare


@pytest.mark.slow
def test_blind_lines_collide_on_the_crossing_and_dmpc_over_an_ideal_radio_does_not(tmp_path):
    out = tmp_path / "cmp"
    t0 = time.perf_counter()
    # 9 s: the blind lines meet at the centre at ~8 s (15 s min-jerk lines, 0.5 s start delay); DMPC stops on arrival
    results = run_compare(out, "crossing", modes=("placeholder", "comm"), seeds=(0,), duration_s=9.0, progress=False)
    wall_s = time.perf_counter() - t0
    data = json.loads((out / "results.json").read_text())
    assert data == results and data["scenario"] == "crossing" and data["summary"] == []
    assert len(data["rows"]) == 2 and all(tuple(r) == ROW_KEYS for r in data["rows"])
    assert (out / "results.png").stat().st_size > 0
    assert (out / "results.txt").read_text().startswith("scenario crossing")
    rows = {r["mode"]: r for r in data["rows"]}
    for mode in ("placeholder", "comm"):
        assert (out / "runs" / f"{mode}-seed0" / "states.npz").is_file()
    own = json.loads((out / "runs" / "placeholder-seed0" / "metrics.json").read_text())
    assert rows["placeholder"]["min_distance_m"] == own["min_inter_drone_distance_m"]
    assert rows["placeholder"]["collisions"] >= 1 and not rows["placeholder"]["success"]
    assert rows["comm"]["collisions"] == 0 and rows["comm"]["min_distance_m"] > 0.2
    assert rows["comm"]["radio_delivered_fraction"] == 1.0  # the crossing's radio is ideal
    print(f"compare crossing placeholder+comm: {wall_s:.1f} s wall; "
          + "; ".join(f"{m}: {r['collisions']} collisions, min {r['min_distance_m']:.3f} m" for m, r in rows.items()))
    assert not list(tmp_path.glob(".*partial*"))  # the staging folder was renamed into place


@pytest.mark.slow
def test_two_jobs_fly_the_same_flights_as_one(tmp_path):
    """--jobs only changes where flights run: the physics is identical step for step, and every row but the
    wall-clock one is identical, except that the tracking errors agree to 1e-6 (relative) rather than to the bit.

    On some CPUs the detector's arithmetic is not bit-stable across how a flight's frames are split over processes,
    so comm's tracking RMSE may differ in its last digits between one job and two. comm's planner reads no camera
    data, so its flight is unchanged."""
    kwargs = {"modes": ("placeholder", "comm"), "seeds": (1,), "duration_s": 3.0, "progress": False}
    one = run_compare(tmp_path / "one", "crossing", **kwargs)
    two = run_compare(tmp_path / "two", "crossing", jobs=2, **kwargs)
    tracking = ("tracking_pos_rmse_m", "tracking_vel_rmse_mps")
    drop = ("real_time_factor", *tracking)
    strip = [[{k: v for k, v in r.items() if k not in drop} for r in res["rows"]] for res in (one, two)]
    assert strip[0] == strip[1]
    for a, b in zip(one["rows"], two["rows"]):
        for key in tracking:
            assert (a[key] is None) == (b[key] is None), key
            if a[key] is not None:
                assert a[key] == pytest.approx(b[key], rel=1e-6), key
    assert [(r["mode"], r["seed"]) for r in two["rows"]] == [("placeholder", 1), ("comm", 1)]
    for mode, seed in [("placeholder", 1), ("comm", 1)]:
        a, b = (np.load(tmp_path / d / "runs" / f"{mode}-seed{seed}" / "states.npz") for d in ("one", "two"))
        np.testing.assert_array_equal(a["pos_world"], b["pos_world"])  # the same physics, step for step
