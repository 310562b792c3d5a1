"""The registry's presets: one agent under a second name with other defaults (``mpcde_paper``)."""

from __future__ import annotations

from mpcde.stacks import get_stack


def test_the_paper_preset_pins_mp_cde_as_published_and_a_field_the_file_sets_wins():
    """``mpcde_paper``: the denied agent with the preset's values wherever the scenario leaves them unset, whatever
    the section's defaults are; what the file (or the code) sets is kept; the preset is written to config.yaml."""
    import dataclasses

    import mpcde
    from mpcde.config.io import to_dict
    from mpcde.config.resolve import resolve
    from mpcde.stacks.builtin import PAPER_PRESET

    paper = mpcde.load_scenario("forest_swarm", mode="mpcde_paper")
    assert get_stack("mpcde_paper").factory is get_stack("denied").factory
    for path, value in PAPER_PRESET.items():
        obj = paper
        for name in path.split("."):
            obj = getattr(obj, name)
        assert obj == value, path
    from mpcde.config.scenario import load_scenario

    cfg = load_scenario("forest_swarm", {"denied": {"fresh_path_age_s": 1.0}}, planner_kind="mpcde_paper")
    assert cfg.denied.fresh_path_age_s == 1.0 and cfg.denied.flight_level_spacing_m == float("inf")
    # a config built in code whose section defaults say otherwise still flies the preset where it left them unset
    shifted = dataclasses.replace(paper, denied=dataclasses.replace(paper.denied, yaw=dataclasses.replace(paper.denied.yaw, tracking_sweep_deg=0.0)))
    assert resolve(shifted).denied.yaw.tracking_sweep_deg == 0.0  # set in code (differs from the default): kept
    flown_again = mpcde.config.scenario.scenario_from_dict(to_dict(paper))
    assert flown_again == paper  # config.yaml holds the preset's values and flies the same
