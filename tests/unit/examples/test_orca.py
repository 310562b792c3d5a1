"""ORCA's velocity program (examples/orca_stack) against a general solver, and its half-planes against the paper's guarantee."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import minimize

ORCA_SOURCE = Path(__file__).resolve().parents[3] / "examples" / "orca_stack" / "mpcde_orca" / "orca.py"
"""The stack's velocity program: numpy only, so it is loaded from its file, without installing the stack."""


@pytest.fixture(scope="module")
def orca():
    spec = importlib.util.spec_from_file_location("orca_under_test", ORCA_SOURCE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up while the file runs
    try:
        spec.loader.exec_module(module)
        yield module
    finally:
        del sys.modules[spec.name]


def _random_feasible_lines(orca, rng, n):
    """n half-planes that all keep a random velocity inside the speed disc."""
    inside = rng.uniform(-0.5, 0.5, 2)
    lines = []
    for _ in range(n):
        angle = rng.uniform(0, 2 * np.pi)
        d = np.array([np.cos(angle), np.sin(angle)])
        normal = np.array([-d[1], d[0]])  # the permitted side: left of d
        point = inside - normal * rng.uniform(0.01, 1.0)  # the line passes right of `inside`
        lines.append(orca.HalfPlane(point, d))
    return lines


def test_the_velocity_is_the_closest_permitted_one_to_the_preferred_as_a_general_solver_finds(orca, rng):
    """Eq. 6 solved by the incremental 2-D program equals SLSQP's minimiser on random feasible programs."""
    for _ in range(25):
        lines = _random_feasible_lines(orca, rng, int(rng.integers(1, 6)))
        pref = rng.uniform(-2.0, 2.0, 2)
        v, feasible = orca.solve_velocity(lines, pref, 1.5)
        assert feasible
        cons = [{"type": "ineq", "fun": (lambda x, l=l: -l.violation(x))} for l in lines]
        cons.append({"type": "ineq", "fun": lambda x: 1.5**2 - x @ x})
        ref = min(
            (minimize(lambda x: np.sum((x - pref) ** 2), x0, constraints=cons, method="SLSQP", tol=1e-12) for x0 in (np.zeros(2), pref)),
            key=lambda r: r.fun if r.success else np.inf,
        )  # fmt: skip
        assert max(l.violation(v) for l in lines) <= 1e-9 and v @ v <= 1.5**2 + 1e-9
        assert np.sum((v - pref) ** 2) <= ref.fun + 1e-6


def test_two_drones_head_on_that_both_take_their_half_do_not_meet_within_the_horizon(orca):
    """The reciprocal guarantee (the paper's Theorem 1): each flies its ORCA velocity; their closest approach within tau is > r."""
    r, tau = 0.8, 2.0
    p_a, p_b = np.array([0.0, 0.0]), np.array([3.0, 0.05])
    v_a, v_b = np.array([1.0, 0.0]), np.array([-1.0, 0.0])  # they would meet in 1.5 s
    line_a = orca.orca_half_plane(p_b - p_a, v_a - v_b, v_a, r, tau, 0.04)
    line_b = orca.orca_half_plane(p_a - p_b, v_b - v_a, v_b, r, tau, 0.04)
    new_a, ok_a = orca.solve_velocity([line_a], v_a, 1.0)
    new_b, ok_b = orca.solve_velocity([line_b], v_b, 1.0)
    assert ok_a and ok_b
    t = np.linspace(0.0, tau, 2001)[:, None]
    gap = np.linalg.norm((p_b + new_b * t) - (p_a + new_a * t), axis=1)
    assert gap.min() >= r - 1e-6
    before = np.linalg.norm((p_b + v_b * t) - (p_a + v_a * t), axis=1)
    assert before.min() < r  # the preferred velocities would have met


def test_a_program_without_a_permitted_velocity_takes_the_least_violating_one(orca):
    """Two opposed half-planes with a gap between them: the fallback sits midway, violating both equally."""
    up = orca.HalfPlane(np.array([0.0, 0.5]), np.array([1.0, 0.0]))  # permitted: left of +x through y = 0.5, y >= 0.5
    down = orca.HalfPlane(np.array([0.0, -0.5]), np.array([-1.0, 0.0]))  # permitted: y <= -0.5
    v, feasible = orca.solve_velocity([up, down], np.array([1.0, 0.0]), 2.0)
    assert not feasible
    assert up.violation(v) == pytest.approx(0.5) and down.violation(v) == pytest.approx(0.5)
