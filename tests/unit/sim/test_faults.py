"""Injected faults: frame drops (random, bursts, windows), detector misses and false boxes, drone failures; seeded and counted."""

from __future__ import annotations

import numpy as np
import pytest

from sim.checks import ConfigError
from sim.faults import FaultInjector, FaultsConfig


def _injector(**kw) -> FaultInjector:
    return FaultInjector(FaultsConfig(**kw), n_drones=3, seed=7, image_size_px=(320, 240))


def test_no_fault_draws_nothing_and_drops_nothing():
    f = _injector()
    state = f.rng.bit_generator.state
    assert not any(f.frame_dropped(d, 0.04 * k) for k in range(100) for d in range(3))
    boxes, scores = f.corrupt(np.ones((2, 4)), np.array([0.9, 0.8]))
    assert boxes.shape == (2, 4) and f.rng.bit_generator.state == state  # a flight without faults is untouched
    assert f.report()["frames_dropped"] == 0 and not FaultsConfig().any


def test_random_drops_come_in_bursts_at_the_set_rate():
    f = _injector(frame_drop_probability=0.1, frame_drop_burst_frames=3)
    lost = np.array([f.frame_dropped(0, 0.04 * k) for k in range(6000)])
    starts = np.flatnonzero(lost[1:] & ~lost[:-1]) + 1
    assert all(lost[s : s + 3].all() for s in starts if s + 3 <= len(lost))  # each loss lasts 3 frames
    # a loss starts with p = 0.1 on frames not in a burst: the lost share is 3p / (1 + 2p) = 0.25
    assert lost.mean() == pytest.approx(0.25, abs=0.03)
    assert f.report()["frames_dropped_per_drone"] == [int(lost.sum()), 0, 0]


def test_windows_drop_every_frame_of_their_drone_and_only_inside():
    f = _injector(frame_drop_windows_s=((1, 2.0, 3.0), (-1, 5.0, 5.5)))
    assert [f.frame_dropped(1, t) for t in (1.99, 2.0, 2.99, 3.0)] == [False, True, True, False]
    assert not f.frame_dropped(0, 2.5) and f.frame_dropped(0, 5.2) and f.frame_dropped(2, 5.2)
    assert f.report()["frames_dropped_in_windows"] == 4


def test_detector_faults_remove_and_add_boxes_inside_the_image_at_the_set_rates():
    f = _injector(detector_miss_probability=0.3, detector_false_positive_rate=0.5)
    kept, added = 0, 0
    for _ in range(4000):
        boxes, scores = f.corrupt(np.tile([[10.0, 10.0, 30.0, 30.0]], (2, 1)), np.array([0.9, 0.9]))
        real = (boxes == [10.0, 10.0, 30.0, 30.0]).all(axis=1)
        kept += int(real.sum())
        fake = boxes[~real]
        added += len(fake)
        assert ((fake[:, 0] >= 0) & (fake[:, 2] <= 320) & (fake[:, 1] >= 0) & (fake[:, 3] <= 240) & (fake[:, 2] > fake[:, 0])).all()
        assert ((scores[~real] >= 0.5) & (scores[~real] <= 1.0)).all()
    assert kept / 8000 == pytest.approx(0.7, abs=0.02) and added / 4000 == pytest.approx(0.5, abs=0.04)
    r = f.report()
    assert r["detections_removed"] == 8000 - kept and r["false_positives_added"] == added


def test_failures_fire_once_at_their_time_and_the_same_seed_draws_the_same():
    f = _injector(drone_failures=((2, 1.0), (0, 0.5)))
    assert f.failures_due(0.49) == [] and f.failures_due(0.5) == [0] and f.failures_due(0.9) == []
    assert f.failures_due(3.0) == [2] and f.failures_due(4.0) == []
    assert [e["drone"] for e in f.report()["drone_failures"]] == [0, 2]
    a, b = (_injector(frame_drop_probability=0.2) for _ in range(2))
    assert [a.frame_dropped(1, 0.0) for _ in range(200)] == [b.frame_dropped(1, 0.0) for _ in range(200)]


@pytest.mark.parametrize("kw, field", [
    ({"frame_drop_probability": 1.5}, "frame_drop_probability"),
    ({"frame_drop_burst_frames": 0}, "frame_drop_burst_frames"),
    ({"frame_drop_windows_s": ((0, 3.0, 2.0),)}, "frame_drop_windows_s[0]"),
    ({"frame_drop_windows_s": ((0.5, 1.0, 2.0),)}, "frame_drop_windows_s[0]"),
    ({"drone_failures": ((-2, 1.0),)}, "drone_failures[0]"),
])  # fmt: skip
def test_bad_faults_name_the_field(kw, field):
    with pytest.raises(ConfigError) as e:
        FaultsConfig(**kw)
    assert e.value.field == field
    with pytest.raises(ConfigError, match=r"^drone_failures\[0\]"):
        FaultsConfig(drone_failures=((4, 1.0),)).check_drones(3)
