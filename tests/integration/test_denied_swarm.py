"""The denied stack in a swarm: its own detector -> tracks -> MINCO keeps drones apart, on camera alone."""

from dataclasses import replace

import pytest

from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run, run_scenario
from mpcde.onboard import denied as agent_denied
from mpcde.onboard import denied as agents
from perception.types import Detection
from sim.types import RgbdFrame


def denied(name: str, seconds: float, perceive: bool = True, seed: int = 0):
    cfg = load_scenario(name, {"duration_s": seconds, "seed": seed, "planner": {"kind": "mpcde"}})
    return replace(cfg, denied=replace(cfg.denied, perceive_neighbours=perceive))


def _timing_free(m: dict) -> dict:
    """Metrics without wall-clock figures (the only run-to-run differences allowed)."""
    out = {k: v for k, v in m.items() if k not in ("wall_time_s", "real_time_factor", "compute_time", "agents")}
    out["agents"] = [{k: v for k, v in a.items() if not k.endswith("_ms_median")} for a in m["agents"]]
    return out


class SpyDenied(agent_denied.DeniedAgent):
    seen: list = []

    def on_frame(self, frame, detections=None):
        SpyDenied.seen.append((self.drone_id, frame, detections))
        super().on_frame(frame, detections)


@pytest.mark.slow  # a flight with cameras, detector and map: 5 s warm, about 30 s with a cold numba cache
def test_each_denied_agent_gets_only_its_own_frame_and_its_own_detections(monkeypatch):
    monkeypatch.setattr(agents, "DeniedAgent", SpyDenied)  # the name make_agent builds the denied stack with
    SpyDenied.seen = []
    run_scenario(prepare_run(denied("crossing", 0.6)))
    assert len(SpyDenied.seen) >= 2 * 10
    for drone_id, frame, detections in SpyDenied.seen:
        assert type(frame) is RgbdFrame and frame.drone_id == drone_id
        assert isinstance(detections, list) and all(type(d) is Detection for d in detections)


@pytest.mark.slow
def test_crossing_pair_avoids_each_other_on_camera_alone_and_collides_blind():
    seeing = run_scenario(prepare_run(denied("crossing", 14.0))).metrics
    assert seeing["drone_drone_collisions"] == 0 and seeing["success"] is True
    assert seeing["min_inter_drone_distance_m"] > 0.5
    assert seeing["track_samples"] > 20 and seeing["tracking_pos_rmse_m"] < 0.4
    assert sum(a["detections"] for a in seeing["agents"]) > 0
    blind = run_scenario(prepare_run(denied("crossing", 14.0, perceive=False))).metrics
    assert blind["drone_drone_collisions"] >= 1  # the same planner without tracks: the test above means something
    assert "tracking_pos_rmse_m" not in blind


@pytest.mark.slow
def test_the_denied_swarm_with_perception_is_reproducible():
    cfg = denied("forest_swarm", 3.0)
    cfg = replace(cfg, run=replace(cfg.run, render_workers=0))
    a = run_scenario(prepare_run(cfg)).metrics
    b = run_scenario(prepare_run(cfg)).metrics
    assert _timing_free(a) == _timing_free(b)
