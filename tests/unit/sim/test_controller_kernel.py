"""The compiled SE(3) law equals its numpy form (wrench and integral state) on random states."""

from __future__ import annotations

import numpy as np

from sim.rotations import rotation_from_quat_xyzw
from sim.vehicle.controller import SE3Controller
from sim.vehicle.params import QuadrotorParams


def test_compiled_law_matches_numpy_over_random_states_and_saturations():
    rng = np.random.default_rng(0)
    n = 64
    params = QuadrotorParams()
    compiled, numpy_form = SE3Controller(params, n), SE3Controller(params, n)
    for k in range(20):
        q = rng.normal(size=(n, 4))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        R = rotation_from_quat_xyzw(q)
        scale = 0.1 if k % 2 else 3.0  # near the reference (the integral runs) and far (tilt limit, thrust floor)
        args = (
            rng.normal(size=(n, 3)) * scale, rng.normal(size=(n, 3)), R, rng.normal(size=(n, 3)) * 2,
            np.zeros((n, 3)), rng.normal(size=(n, 3)), rng.normal(size=(n, 3)) * 5, rng.uniform(-4, 4, n), rng.normal(size=n), 1 / 240,
        )  # fmt: skip
        a = compiled.step(*args)
        b = numpy_form.step_numpy(*args)
        np.testing.assert_allclose(a, b, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(compiled.integral, numpy_form.integral, rtol=0, atol=1e-15)
    assert np.any(np.abs(compiled.integral) > 0)
