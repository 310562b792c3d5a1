"""YawPlannerConfig: MP-CDE defaults and one-line errors naming the field."""

from __future__ import annotations

import dataclasses
import math

import pytest

from planners.yaw import YawPlannerConfig


def test_defaults_are_the_papers():
    cfg = YawPlannerConfig()
    assert (cfg.period_s, cfg.n_steps, cfg.yaw_rate_max_radps, cfg.epsilon) == (0.1, 12, 2.0, 1.2)
    assert (cfg.alpha, cfg.beta, cfg.n_rays, cfg.t_hold_s, cfg.hysteresis_s) == (0.6, 0.4, 72, 0.6, 0.1)
    assert (cfg.fov_h_deg, cfg.fov_v_deg) == (85.0, 58.0)
    assert cfg.tau_thr_s == pytest.approx(1.2 * math.pi / 2.0)
    assert cfg.max_step_rad == pytest.approx(0.2)


@pytest.mark.parametrize(
    "field, value",
    [
        ("period_s", 0.0),
        ("period_s", float("nan")),
        ("n_steps", 0),
        ("n_steps", 2.0),
        ("n_steps", True),
        ("n_candidates", 2),
        ("yaw_rate_max_radps", 0.9),  # 2 pi / 64 > 0.09 rad: adjacent candidates not connected
        ("yaw_rate_max_radps", -2.0),
        ("epsilon", 0.0),
        ("hysteresis_s", -0.1),
        ("alpha", -0.6),
        ("beta", float("inf")),
        ("turn_penalty", -1.0),
        ("n_rays", 1),
        ("fov_h_deg", 0.0),
        ("fov_h_deg", 355.0),  # the sector plus one step would wrap onto itself
        ("fov_v_deg", 180.0),
        ("sensing_range_m", 0.0),
        ("ray_step_m", 0.0),
        ("sensing_range_m", 0.1),  # shorter than one ray step (0.15 m)
        ("detection_range_m", -1.0),
        ("v_max_mps", 0.0),
        ("t_hold_s", -0.6),
        ("window_s", -1.0),
        ("safety_sample_s", 0.0),
        ("safety_horizon_s", 1.9),  # below tau_thr + hysteresis: exploring could never start
        ("distance_eps_m", 0.0),
        ("visibility_sigma_ref_m", 0.0),
        ("visibility_weight_max", 0.5),
        ("still_speed_mps", -0.1),
    ],
)
def test_invalid_values_raise_one_line_errors_naming_the_field(field, value):
    with pytest.raises(ValueError, match=rf"^{field}=") as info:
        if field in {f.name for f in dataclasses.fields(YawPlannerConfig)}:
            YawPlannerConfig(**{field: value})
        else:  # a class constant: a subclass overrides it
            type("Overridden", (YawPlannerConfig,), {field: value})()
    assert "\n" not in str(info.value)
    assert ": " in str(info.value)  # <field>=<value>: <allowed> (sim.checks wording)


def test_alpha_and_beta_cannot_both_be_zero():
    with pytest.raises(ValueError, match="alpha \\+ beta"):
        YawPlannerConfig(alpha=0.0, beta=0.0)


def test_coarser_lattice_with_a_faster_yaw_is_accepted():
    coarse = type("CoarseLattice", (YawPlannerConfig,), {"n_candidates": 16})  # a class constant
    cfg = coarse(yaw_rate_max_radps=4.0)
    assert cfg.max_hop == 1
