"""The compiled obstacle distance equals its numpy form, inside, outside, above and below trees and yawed boxes."""

from __future__ import annotations

import numpy as np

from sim.obstacles import ObstacleField, generate_obstacles


def test_compiled_distance_matches_numpy_everywhere():
    rng = np.random.default_rng(1)
    obstacles = generate_obstacles(rng, (20.0, 20.0), 8.0, np.zeros((0, 2)), 0.0, box_fraction=0.5)
    assert {o.kind for o in obstacles} == {"tree", "box"}
    field = ObstacleField(obstacles)
    pts = np.column_stack([rng.uniform(-10, 10, (5000, 2)), rng.uniform(-1.0, 6.0, 5000)])
    a, b = field.distance(pts), field.distance_numpy(pts)
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    assert (a < 0).any() and (a > 0).any()  # points inside obstacles and outside


def test_no_obstacles_is_infinitely_far():
    assert np.isinf(ObstacleField(()).distance(np.zeros((3, 3)))).all()
