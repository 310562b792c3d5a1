"""The VIO stand-in: drift grows as a random walk; same seed, same estimates."""

import numpy as np
import pytest

from sim.ground_truth import TrueState
from sim.pose_estimate import PoseEstimateConfig, PoseEstimator


def truth_at(t: float, n: int) -> TrueState:
    return TrueState(t, np.zeros((n, 3)), np.zeros((n, 3)), np.tile([0, 0, 0, 1.0], (n, 1)), np.tile(np.eye(3), (n, 1, 1)), np.zeros((n, 3)), np.zeros(n, bool), np.zeros(n, bool))


def run(seed: int, cfg: PoseEstimateConfig, n: int = 2000, seconds: float = 16.0, dt: float = 0.04):
    est = PoseEstimator(cfg, n, seed)
    out = None
    for k in range(1, int(seconds / dt) + 1):
        out = est.update(truth_at(k * dt, n))
    return est, out


def test_position_drift_is_a_random_walk_with_its_configured_intensity():
    cfg = PoseEstimateConfig(pos_noise_m=0.0, pos_drift_m_per_sqrt_s=0.01)
    est, _ = run(0, cfg)
    # after t = 16 s the bias per axis has std sigma sqrt(t) = 0.04 m
    assert np.std(est.bias_pos_world) == pytest.approx(0.04, rel=0.05)


def test_same_seed_same_estimates_and_noise_free_config_is_exact():
    cfg = PoseEstimateConfig()
    _, a = run(3, cfg, n=3, seconds=1.0)
    _, b = run(3, cfg, n=3, seconds=1.0)
    assert all(np.array_equal(x.pos_world, y.pos_world) for x, y in zip(a, b))
    zero = PoseEstimateConfig(0.0, 0.0, 0.0, 0.0, 0.0)
    _, c = run(3, zero, n=3, seconds=1.0)
    assert all(np.allclose(x.pos_world, 0.0) and np.allclose(x.quat_xyzw, [0, 0, 0, 1]) for x in c)


def test_negative_noise_is_rejected_with_the_field_named():
    with pytest.raises(ValueError, match="pos_noise_m"):
        PoseEstimateConfig(pos_noise_m=-1.0)


def test_extrapolated_moves_the_estimate_at_its_constant_velocity_and_copies_it():
    from sim.types import PoseEstimate

    est = PoseEstimate(2.0, np.array([1.0, -2.0, 1.5]), np.array([0.5, 0.0, -0.2]), np.array([0, 0, 0, 1.0]), np.zeros(3))
    pos, vel = est.extrapolated(2.4)
    np.testing.assert_allclose(pos, [1.2, -2.0, 1.42])
    np.testing.assert_allclose(vel, [0.5, 0.0, -0.2])
    back, _ = est.extrapolated(1.0)  # before the estimate: backwards along the same line
    np.testing.assert_allclose(back, [0.5, -2.0, 1.7])
    vel[0] = 9.0  # the returned velocity is the caller's, not the frozen estimate's
    assert est.vel_world[0] == 0.5
    np.testing.assert_array_equal(est.extrapolated(2.0)[0], est.pos_world)
