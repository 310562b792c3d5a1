"""The stacks' cross-field rules: the DMPC round's step, the stacks that fly without obstacles in a fixed box
(``mlr``, ``admm``), and the denied stack's flight levels.

Flight levels (``denied.flight_level_spacing_m``): drone k of N cruises at z_k = z_c + (k - (N - 1) / 2) s,
z_c the mean of its own start and goal altitudes (:class:`mpcde.config.denied.DeniedAgentConfig`). Two rules
make the levels what they promise: every drone's z_c is the same, so that the levels are distinct and s apart;
and the lowest and highest levels lie within the altitudes a layout may use (:data:`LEVEL_ALTITUDES_M`), the
lowest level's layer keeping the front end's clearance (``denied.front_end_clearance_m``) from the ground.
The same clearance bounds every start and goal of a stack that flies the denied planner
(:func:`check_denied_ground_clearance`): the camera maps the ground, so a search from or to a point nearer it fails.

Each is a registry entry's ``check`` (:mod:`mpcde.stacks.builtin`), which
:meth:`mpcde.config.scenario.ScenarioConfig.__post_init__` calls for the scenario's stack.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from mpcde.errors import ConfigError

if TYPE_CHECKING:
    from mpcde.config.scenario import ScenarioConfig, WorldConfig

__all__ = [
    "LEVEL_ALTITUDES_M", "check_admm", "check_denied_ground_clearance", "check_dmpc_round", "check_flight_levels",
    "check_mlr", "flight_level_m",
]


def _refuse_obstacles(world: WorldConfig, kind: str, why: str) -> None:
    """ConfigError if the world has static obstacles: planner.kind ``kind`` cannot avoid them (``why``)."""
    why = f"{why}; fly obstacles with planner.kind 'dmpc' (--mode comm)"
    if world.obstacles:
        raise ConfigError("world.obstacles", [o.kind for o in world.obstacles], f"none for planner.kind {kind!r}: {why}")
    if world.obstacle_density_per_100m2 > 0:
        density = world.obstacle_density_per_100m2
        raise ConfigError("world.obstacle_density_per_100m2", density, f"0 for planner.kind {kind!r}: {why}")


def _require_inside_box(starts: np.ndarray, goals: np.ndarray, planner: Any, box_name: str, section: str) -> None:
    """ConfigError naming the first start or goal (n, 3) [m] outside ``planner``'s pos_min_world..pos_max_world."""
    lo, hi = np.asarray(planner.pos_min_world), np.asarray(planner.pos_max_world)
    for name, pts in (("drones.starts", starts), ("drones.goals", goals)):
        outside = np.flatnonzero(np.any((pts < lo) | (pts > hi), axis=1))
        if outside.size:
            i = int(outside[0])
            box = f"[{', '.join(f'{v:g}' for v in lo)}] to [{', '.join(f'{v:g}' for v in hi)}] m"
            allowed = f"inside {box_name} {box} (the arena less {section}.arena_margin_m, {section}.altitude_range_m)"
            raise ConfigError(f"{name}[{i}]", [round(float(v), 3) for v in pts[i]], allowed)


def check_dmpc_round(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray) -> None:
    """ConfigError unless the DMPC QP's step is one radio round (``dmpc`` and ``auto``: one DMPC round per step)."""
    step, rate = cfg.dmpc.qp.step_s, cfg.radio.rate_hz
    if abs(step * rate - 1.0) > 1e-6:
        raise ConfigError("dmpc.qp.step_s", step, f"must equal 1 / radio.rate_hz = {1.0 / rate:g} s (one DMPC round per step)")


def check_mlr(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray) -> None:
    """The cross-field rules of ``planner.kind: mlr`` (:mod:`mpcde.onboard.mlr`) for the layout's starts and goals (N, 3) [m]; raises ConfigError."""
    mlr, radio, world = cfg.mlr, cfg.radio, cfg.world
    if abs(mlr.round_s * radio.rate_hz - 1.0) > 1e-6:
        allowed = f"must equal 1 / radio.rate_hz = {1.0 / radio.rate_hz:g} s (one MLR round per radio round)"
        raise ConfigError("mlr.round_s", mlr.round_s, allowed)
    if not radio.delay_s < mlr.round_s:
        allowed = f"< mlr.round_s = {mlr.round_s:g} s for planner.kind 'mlr' (messages are read in the next round)"
        raise ConfigError("radio.delay_s", radio.delay_s, allowed)
    _refuse_obstacles(world, "mlr", "MLR-DMPC has no obstacle constraints")
    planner = mlr.planner_config(len(starts), world.arena_size_m)  # M < N and the flying box
    _require_inside_box(starts, goals, planner, "MLR-DMPC's flying box", "mlr")


def check_admm(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray) -> None:
    """The cross-field rules of ``planner.kind: admm`` (:mod:`mpcde.onboard.admm`) for the layout's starts and goals (N, 3) [m]; raises ConfigError."""
    admm, radio, world = cfg.admm, cfg.radio, cfg.world
    if admm.radio_rate_from_step:  # the rate resolve() gives the radio (mpcde/config/resolve.py)
        radio = replace(radio, rate_hz=admm.radio_rate_hz)
    elif abs(radio.rate_hz * admm.step_s - admm.rounds_per_step) > 1e-6:
        allowed = (
            f"must equal 2 x the ADMM iterations per step / admm.step_s = {admm.radio_rate_hz:g} Hz for planner.kind 'admm' (one "
            "radio sub-round per ADMM exchange), or set admm.radio_rate_from_step: true"
        )
        raise ConfigError("radio.rate_hz", radio.rate_hz, allowed)
    if not radio.delay_s < admm.sub_round_s:
        allowed = f"< one ADMM sub-round, admm.step_s / (2 x the iterations per step) = {admm.sub_round_s:g} s for planner.kind 'admm'"
        raise ConfigError("radio.delay_s", radio.delay_s, allowed)
    if cfg.physics.physics_hz < radio.rate_hz - 1e-9:
        allowed = f">= the ADMM radio rate {radio.rate_hz:g} Hz for planner.kind 'admm' (a tick per sub-round)"
        raise ConfigError("physics.physics_hz", cfg.physics.physics_hz, allowed)
    _refuse_obstacles(world, "admm", "the ADMM formation OCP has no obstacle constraints")
    if cfg.planner.line_speed_mps > admm.limits.v_max_mps:
        allowed = f"<= admm.limits.v_max_mps = {admm.limits.v_max_mps:g} m/s for planner.kind 'admm' (the own reference's speed)"
        raise ConfigError("planner.cruise_speed_mps", cfg.planner.line_speed_mps, allowed)
    planner = admm.planner_config(cfg.world.arena_size_m)  # the soft position box fits the arena
    _require_inside_box(starts, goals, planner, "the ADMM position box", "admm")
    if admm.solver == "dsqp":
        return  # dSQP keeps the neighbours apart: any start flies
    # no collision avoidance: the drones must start in the goals' formation (moved to the starts' centroid)
    slots = goals - goals.mean(axis=0) + starts.mean(axis=0)
    offset = np.linalg.norm(starts - slots, axis=1)
    if np.any(offset > admm.max_start_offset_m):
        i = int(np.argmax(offset))
        allowed = (
            f"within admm.max_start_offset_m = {admm.max_start_offset_m:g} m of its slot in the goals' formation "
            f"({offset[i]:.2f} m off) for planner.kind 'admm': it has no collision avoidance"
        )
        raise ConfigError(f"drones.starts[{i}]", [round(float(v), 3) for v in starts[i]], allowed)


LEVEL_ALTITUDES_M = (0.3, 20.0)
"""(lowest, highest) altitude [m] a flight level may have: those a layout's starts and goals may have."""


def flight_level_m(centre_m: float, drone_id: int, drones: int, spacing_m: float) -> float:
    """z_k = z_c + (k - (N - 1) / 2) s [m]: the level of drone ``drone_id`` of ``drones`` about ``centre_m`` [m]."""
    return centre_m + (drone_id - 0.5 * (drones - 1)) * spacing_m


def check_flight_levels(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray) -> None:
    """ConfigError if the flight levels of the layout's starts and goals (N, 3) [m] are not distinct or leave the altitudes."""
    spacing = cfg.denied.flight_level_spacing_m
    if not np.isfinite(spacing):
        return
    centres = 0.5 * (starts[:, 2] + goals[:, 2])
    odd = np.flatnonzero(np.abs(centres - centres[0]) > 1e-6)
    if odd.size:
        i = int(odd[0])
        allowed = (
            f"inf (no levels) unless every drone's start and goal altitudes share one mean: drone {i}'s is "
            f"{centres[i]:.3g} m, drone 0's {centres[0]:.3g} m (the levels are spaced about it)"
        )
        raise ConfigError("denied.flight_level_spacing_m", spacing, allowed)
    n = len(starts)
    # the lowest level's layer (held within s / 8 of it) must keep the front end's clearance from the ground the
    # camera maps below it: a level nearer the ground is one whose every search fails
    # (docs/results/denied_default.md#ring-of-7)
    ground_m = cfg.denied.front_end_clearance_m
    lo, hi = max(LEVEL_ALTITUDES_M[0], ground_m + spacing / 8.0), LEVEL_ALTITUDES_M[1]
    lowest, highest = flight_level_m(centres[0], 0, n, spacing), flight_level_m(centres[0], n - 1, n, spacing)
    if n > 1 and not (lowest >= lo - 1e-9 and highest <= hi + 1e-9):  # to rounding: 1.5 - 2.5 x 0.4 may be 0.4999...
        half = 0.5 * (n - 1)
        largest = min((centres[0] - max(LEVEL_ALTITUDES_M[0], ground_m)) / (half + 0.125), (hi - centres[0]) / half)
        allowed = (
            f"<= {largest:.3g} m for {n} drones about {centres[0]:.3g} m (levels from {lowest:.3g} to {highest:.3g} m; "
            f"the lowest must keep denied.front_end_clearance_m + s / 8 = {lo:.3g} m above the ground, the highest <= {hi:g} m)"
        )
        raise ConfigError("denied.flight_level_spacing_m", spacing, allowed)


def check_denied_ground_clearance(cfg: ScenarioConfig, starts: np.ndarray, goals: np.ndarray) -> None:
    """ConfigError naming the first start or goal (N, 3) [m] below ``denied.front_end_clearance_m``.

    The denied planner's front end keeps that clearance from every occupied voxel, the ground its camera maps
    among them, so every search from or to such a point fails and the drone never leaves or never arrives
    (docs/results/denied_default.md#ring-of-7 shows it for a flight level on the floor).
    """
    ground_m = cfg.denied.front_end_clearance_m
    for name, pts in (("drones.starts", starts), ("drones.goals", goals)):
        low = np.flatnonzero(pts[:, 2] < ground_m - 1e-9)
        if low.size:
            i = int(low[0])
            allowed = (
                f"an altitude >= denied.front_end_clearance_m = {ground_m:g} m (the denied planner keeps that clearance "
                f"from the ground it maps)"
            )
            raise ConfigError(f"{name}[{i}]", [round(float(v), 3) for v in pts[i]], allowed)
