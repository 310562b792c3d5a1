"""The auto mode flown in full physics with rendering: DMPC while the radio delivers, MP-CDE through an outage."""

from dataclasses import replace

import pytest

from mpcde.config.scenario import load_scenario
from mpcde.flight.loop import prepare_run, run_scenario

pytestmark = pytest.mark.slow


def _fly(kind: str, jamming=(), handover: str = "halt"):
    cfg = load_scenario("crossing", {"seed": 0, "auto": {"handover": handover}})
    cfg = replace(cfg, planner=replace(cfg.planner, kind=kind), radio=replace(cfg.radio, jamming_windows_s=jamming))
    cfg.__post_init__()
    return run_scenario(prepare_run(cfg)).metrics


def test_with_a_perfect_radio_auto_flies_exactly_as_comm():
    """Every plan fresh and every track explained by one: the fused neighbours are the radio's, so the flight is DMPC's."""
    auto, comm = _fly("auto"), _fly("dmpc")
    for a in auto["agents"]:
        assert a["mode_switches"] == 0 and a["dmpc"]["substituted_plans"] == 0 and a["dmpc"]["unknown_tracks"] == 0
    for key in ("min_inter_drone_distance_m", "mission_time_s", "collisions", "success"):
        assert auto[key] == comm[key], key


@pytest.mark.parametrize("handover", ["continue", "halt"])
def test_through_a_radio_outage_auto_falls_back_to_the_denied_stack_and_returns(handover):
    """Receivers deaf from 1.0 s to 4.0 s: the last plans heard were sent at 0.8 s, silence exceeds 1.0 s at the
    2.0 s round; the first plans after the outage are sent at 4.0 s and heard at the 4.2 s round.

    ``continue``: the denied half plans from the switch on. ``halt``: each drone flies its plan of 0.8 s or
    1.0 s (the last one solved before the silence) toward its halt 3 s later and would then turn; the radio
    returns first, so the denied half never plans."""
    m = _fly("auto", jamming=((1.0, 4.0),), handover=handover)
    for a in m["agents"]:
        assert [(s["time_s"], s["to"]) for s in a["switches"]] == [(2.0, "denied"), (4.2, "comm")]
        if handover == "continue":
            assert a["denied"]["replans"] >= 1 and a["halting_handovers"] == []
        else:
            (h,) = a["halting_handovers"]
            assert 2.0 < h["halt_s"] <= 4.0 + 1e-9 and a["denied"]["replans"] == 0
    assert m["success"] and m["collisions"] == 0
    assert m["tracking_pos_rmse_m"] is not None and m["tracking_pos_rmse_m"] < 0.5
