"""Optimal reciprocal collision avoidance in the plane (van den Berg, Guy, Lin, Manocha, ISRR 2011).

For agent A among neighbours B with relative position p = p_B - p_A,
relative velocity v = v_A - v_B, combined radius r and time horizon tau, the
velocity obstacle VO^tau_{A|B} is the set of relative velocities that collide
within tau: the truncated cone with apex 0, legs tangent to the disc D(p, r)
and cut off by the disc D(p / tau, r / tau). u is the smallest change of the
relative velocity that leaves it (to the nearest point of the boundary), n its
outward normal; A takes half the responsibility:

    ORCA^tau_{A|B} = { v' : (v' - (v_A + u / 2)) . n >= 0 }          (paper, Eq. 5)

and flies the permitted velocity closest to its preferred one,

    v_A^new = argmin_{v in D(0, v_max) ∩ (∩_B ORCA_{A|B})} || v - v_pref ||   (Eq. 6),

a 2-D linear program in the half-planes with a quadratic objective, solved
exactly by randomised-incremental style passes (:func:`solve_velocity`). When
the half-planes leave no velocity (dense crowds, or a neighbour already
inside r), the velocity that minimises the largest violation is taken
instead (the paper's Sec. 5.2, a 3-D linear program solved by projection).

Each line is (point, direction) with the permitted side on the left of the
direction: v is permitted when det(direction, point - v) <= 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["HalfPlane", "orca_half_plane", "solve_velocity"]

EPS = 1e-9


@dataclass(frozen=True)
class HalfPlane:
    """A permitted half-plane of velocities: v with det(direction, point - v) <= 0 (left of the directed line)."""

    point: np.ndarray  # (2,) [m/s]
    direction: np.ndarray  # (2,) unit

    def violation(self, v: np.ndarray) -> float:
        """det(direction, point - v) [m/s]: > 0 when ``v`` (2,) is outside, by that distance."""
        return _det(self.direction, self.point - v)


def _det(a: np.ndarray, b: np.ndarray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def orca_half_plane(
    rel_pos: np.ndarray, rel_vel: np.ndarray, own_vel: np.ndarray, radius_m: float, horizon_s: float, step_s: float
) -> HalfPlane:
    """ORCA^tau_{A|B} (Eq. 5) for a neighbour at ``rel_pos`` = p_B - p_A (2,) [m] with ``rel_vel`` = v_A - v_B (2,) [m/s].

    Args:
        own_vel: (2,) v_A [m/s].
        radius_m: combined radius r [m].
        horizon_s: tau [s].
        step_s: the replanning period [s]: when the discs already overlap the
            cut-off disc of time ``step_s`` is used, so the pair separates within one step.
    """
    dist_sq = float(rel_pos @ rel_pos)
    r_sq = radius_m * radius_m
    if dist_sq > r_sq:
        w = rel_vel - rel_pos / horizon_s  # from the cut-off disc's centre to the relative velocity
        w_sq = float(w @ w)
        dot1 = float(w @ rel_pos)
        if dot1 < 0.0 and dot1 * dot1 > r_sq * w_sq:  # nearest boundary point on the cut-off circle
            w_len = np.sqrt(w_sq)
            unit_w = w / w_len
            direction = np.array([unit_w[1], -unit_w[0]])
            u = (radius_m / horizon_s - w_len) * unit_w
        else:  # nearest boundary point on a leg of the cone
            leg = np.sqrt(dist_sq - r_sq)
            x, y = rel_pos
            if _det(rel_pos, w) > 0.0:  # left leg
                direction = np.array([x * leg - y * radius_m, x * radius_m + y * leg]) / dist_sq
            else:  # right leg
                direction = -np.array([x * leg + y * radius_m, -x * radius_m + y * leg]) / dist_sq
            u = float(rel_vel @ direction) * direction - rel_vel
    else:  # already overlapping: leave within one step
        w = rel_vel - rel_pos / step_s
        w_len = max(float(np.linalg.norm(w)), EPS)
        unit_w = w / w_len
        direction = np.array([unit_w[1], -unit_w[0]])
        u = (radius_m / step_s - w_len) * unit_w
    return HalfPlane(point=own_vel + 0.5 * u, direction=direction)


def _lp1(lines: list[HalfPlane], k: int, radius: float, opt: np.ndarray, direction_opt: bool) -> np.ndarray | None:
    """The best point on line ``k`` within the speed disc and the lines before it (None: none)."""
    line = lines[k]
    dot = float(line.point @ line.direction)
    disc = dot * dot + radius * radius - float(line.point @ line.point)
    if disc < 0.0:  # the line misses the speed disc
        return None
    s = np.sqrt(disc)
    t_left, t_right = -dot - s, -dot + s
    for i in range(k):
        denom = _det(line.direction, lines[i].direction)
        numer = _det(lines[i].direction, line.point - lines[i].point)
        if abs(denom) <= EPS:  # parallel
            if numer < 0.0:
                return None
            continue
        t = numer / denom
        if denom >= 0.0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return None
    if direction_opt:
        t = t_right if float(opt @ line.direction) > 0.0 else t_left
    else:
        t = float(np.clip(line.direction @ (opt - line.point), t_left, t_right))
    return line.point + t * line.direction


def _lp2(lines: list[HalfPlane], radius: float, opt: np.ndarray, direction_opt: bool) -> tuple[np.ndarray, int]:
    """(the permitted velocity closest to ``opt``, the first line that could not be met or len(lines))."""
    if direction_opt:
        result = opt * radius
    elif float(opt @ opt) > radius * radius:
        result = opt / np.linalg.norm(opt) * radius
    else:
        result = opt.copy()
    for i, line in enumerate(lines):
        if line.violation(result) > 0.0:
            new = _lp1(lines, i, radius, opt, direction_opt)
            if new is None:
                return result, i
            result = new
    return result, len(lines)


def _lp3(lines: list[HalfPlane], begin: int, radius: float, result: np.ndarray) -> np.ndarray:
    """The velocity in the speed disc minimising the largest violation of ``lines`` (from line ``begin`` on)."""
    distance = 0.0
    for i in range(begin, len(lines)):
        if lines[i].violation(result) > distance:
            projected = []
            for j in range(i):
                det = _det(lines[i].direction, lines[j].direction)
                if abs(det) <= EPS:
                    if float(lines[i].direction @ lines[j].direction) > 0.0:
                        continue  # same direction: line j is met wherever line i is
                    point = 0.5 * (lines[i].point + lines[j].point)
                else:
                    point = lines[i].point + (_det(lines[j].direction, lines[i].point - lines[j].point) / det) * lines[i].direction
                d = lines[j].direction - lines[i].direction
                projected.append(HalfPlane(point, d / max(float(np.linalg.norm(d)), EPS)))
            normal = np.array([-lines[i].direction[1], lines[i].direction[0]])
            candidate, fail = _lp2(projected, radius, normal, True)
            if fail == len(projected):
                result = candidate
            distance = lines[i].violation(result)
    return result


def solve_velocity(lines: list[HalfPlane], v_pref: np.ndarray, v_max: float) -> tuple[np.ndarray, bool]:
    """Eq. 6: the velocity (2,) [m/s] in ``lines`` and ||v|| <= ``v_max`` closest to ``v_pref`` (2,).

    Returns:
        (velocity, feasible): feasible False when the half-planes leave no
        velocity, and the velocity minimising the largest violation was taken.
    """
    v_pref = np.asarray(v_pref, float)
    result, fail = _lp2(lines, v_max, v_pref, False)
    if fail < len(lines):
        return _lp3(lines, fail, v_max, result), False
    return result, True
