"""The pipeline measurement source: flatness attitudes, and render -> detect -> back-project against truth."""

import numpy as np
import pytest

from mpcde.evals.tracking import TrackingScenario
from mpcde.evals.tracking_pipeline import PipelineMeasurements, background_trees, flat_attitudes


def test_hover_attitude_is_level_and_heads_along_the_velocity():
    R = flat_attitudes(np.array([[0.0, 1.0, 0.0]]), np.zeros((1, 3)))[0]
    np.testing.assert_allclose(R[:, 2], [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(R[:, 0], [0, 1, 0], atol=1e-12)


def test_attitudes_are_rotations_whose_thrust_axis_carries_the_acceleration(rng=np.random.default_rng(3)):
    vel, acc = rng.normal(0, 2, (50, 3)), rng.normal(0, 3, (50, 3))
    R = flat_attitudes(vel, acc)
    np.testing.assert_allclose(R @ np.swapaxes(R, 1, 2), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, atol=1e-12)
    thrust = acc + [0, 0, 9.81]
    np.testing.assert_allclose(R[:, :, 2], thrust / np.linalg.norm(thrust, axis=1, keepdims=True), atol=1e-12)
    # the heading: body y is perpendicular to the horizontal velocity direction, body x points along it
    heading = np.arctan2(vel[:, 1], vel[:, 0])
    x_c = np.stack([np.cos(heading), np.sin(heading), 0 * heading], 1)
    np.testing.assert_allclose(np.einsum("ni,ni->n", R[:, :, 1], x_c), 0, atol=1e-12)
    assert np.all(np.einsum("ni,ni->n", R[:, :, 0], x_c) > 0)


def test_background_is_seeded_and_stays_out_of_the_targets_region():
    a, b = background_trees(4, 10, np.zeros(3), 0.0), background_trees(4, 10, np.zeros(3), 0.0)
    assert a == b and a != background_trees(5, 10, np.zeros(3), 0.0)
    assert all(9.0 <= np.hypot(*t.center_xy) <= 16.0 for t in a)


def test_bad_options_and_weights_are_refused(tmp_path):
    with pytest.raises(ValueError, match="batch_frames"):
        PipelineMeasurements(batch_frames=0)
    with pytest.raises(ValueError, match="weights"):
        PipelineMeasurements(weights=str(tmp_path / "missing.pt"))


@pytest.mark.slow
def test_rendered_detected_backprojected_measurements_lie_near_the_truth():
    """Three drones 3-7 m ahead for 24 frames: most are measured, within a few cm + 1.5 % of range."""
    t = np.arange(1, 25) * 0.04
    pos = np.zeros((t.size, 3, 3))
    for j, (r, az) in enumerate([(3.0, -0.35), (5.0, 0.25), (7.0, 0.0)]):
        a = az + 0.2 * np.sin(0.5 * t)
        pos[:, j] = np.stack([r * np.cos(a), r * np.sin(a), 1.5 + 0.2 * np.sin(t)], 1)
    vel = np.gradient(pos, t, axis=0)
    scenario = TrackingScenario(t, np.array([0.0, 0.0, 1.5]), pos, vel)
    run = PipelineMeasurements().run(scenario, seed=0)
    assert len(run.frames) == t.size and run.n_visible == 3 * t.size
    errors, ranges, false = [], [], 0
    for k, ms in enumerate(run.frames):
        for m in ms:
            d = np.linalg.norm(pos[k] - m.pos_world, axis=1)
            if d.min() > 0.5:
                false += 1
                continue
            errors.append(d.min())
            ranges.append(np.linalg.norm(pos[k, d.argmin()] - [0.07, 0, 1.51]))
            assert np.all(np.linalg.eigvalsh(m.cov_world) > 0)
    assert false <= 2
    assert len(errors) >= 0.8 * 3 * t.size
    assert np.median(np.asarray(errors) / (0.05 + 0.015 * np.asarray(ranges))) < 1.0
