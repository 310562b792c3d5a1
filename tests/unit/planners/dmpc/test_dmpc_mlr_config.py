"""MLR-DMPC settings and reference trajectories: invalid fields are refused in one line; Eq. 12 is exact."""

from __future__ import annotations

import numpy as np
import pytest

from planners.dmpc.mlr.config import MlrConfig
from planners.dmpc.mlr.trajectory import ReferenceTrajectory, TrajectoryId, positions_at_each
from planners.dmpc.model import rollout


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("n_uavs", 1, "n_uavs=1: an integer >= 2"),
        ("n_cus", 16, "n_cus=16: an integer < n_uavs=16 (M < N)"),
        ("n_cus", 0, "n_cus=0: an integer >= 1"),
        ("round_s", 0.0, "round_s=0.0: a finite number > 0"),
        ("horizon_rounds", 1, "horizon_rounds=1: an integer >= 2"),
        ("collision_checks_per_round", 3, "collision_checks_per_round=3: a multiple of input_steps_per_round=2"),
        ("d_hat_min_m", -0.1, "d_hat_min_m=-0.1: a finite number > 0"),
        ("bvc_margin_m", -1.0, "bvc_margin_m=-1.0: a finite number >= 0"),
        ("downwash", 0.5, "downwash=0.5: a finite number >= 1"),
        ("trigger", "fifo", "trigger='fifo': one of rr, db, ht"),
        ("max_candidates", 0, "max_candidates=0: an integer >= 1"),
        ("osqp_polish", 1, "osqp_polish=1: True or False"),
        ("limits", 1.0, "limits=1.0: a KinematicLimits (a mapping of its fields in a scenario file)"),
    ],
)
def test_invalid_fields_are_refused_with_a_one_line_message(field: str, value: object, message: str) -> None:
    kwargs = {field: value}
    if field == "collision_checks_per_round":
        kwargs["input_steps_per_round"] = 2
    with pytest.raises(ValueError) as err:
        MlrConfig(**kwargs)
    assert str(err.value) == message and "\n" not in str(err.value)


def test_derived_times() -> None:
    cfg = MlrConfig(input_steps_per_round=2, collision_checks_per_round=4)
    assert cfg.input_step_s == pytest.approx(0.1) and cfg.n_inputs == 30
    assert cfg.check_step_s == pytest.approx(0.05) and cfg.n_checks == 60 and cfg.horizon_s == pytest.approx(3.0)


def test_trajectory_matches_the_rollout_at_the_knots_and_is_smooth_between(rng) -> None:
    x0 = rng.normal(size=9)
    u = rng.normal(size=(6, 3))
    traj = ReferenceTrajectory(TrajectoryId(3, 1), 0.8, x0, u, 0.2)
    knots = rollout("triple", 0.2, x0, u)
    np.testing.assert_allclose(traj.states_at(0.8 + 0.2 * np.arange(7)), knots, atol=1e-12)
    t = 0.8 + np.linspace(0.0, 1.2, 241)
    x = traj.states_at(t)
    # velocity is the derivative of position (central differences)
    dt = t[1] - t[0]
    np.testing.assert_allclose((x[2:, :3] - x[:-2, :3]) / (2 * dt), x[1:-1, 3:6], atol=1e-3)
    with pytest.raises(ValueError, match="before t_start_s"):
        traj.states_at(np.array([0.5]))
    assert not traj.inputs.flags.writeable


def test_batched_positions_equal_each_trajectory_evaluated_alone(rng) -> None:
    trajs = [ReferenceTrajectory(TrajectoryId(k, 0), 0.2 * k, rng.normal(size=9), rng.normal(size=(5 + k, 3)), 0.1)
             for k in range(6)]
    # inside an input step, on a knot, and past the last input (zero jerk, coasting)
    times = np.array([tr.t_start_s + dt for tr, dt in zip(trajs, [0.0, 0.05, 0.3, 0.57, 1.1, 4.0])])
    want = np.array([tr.positions_at(np.array([t]))[0] for tr, t in zip(trajs, times)])
    np.testing.assert_allclose(positions_at_each(trajs, times), want, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="before"):
        positions_at_each(trajs[:1], np.array([trajs[0].t_start_s - 0.1]))
