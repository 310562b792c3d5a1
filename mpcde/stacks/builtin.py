"""The stacks this package ships, as registry entries (:mod:`mpcde.stacks.registry`).

Each entry's factory imports its agent when it first builds one, so reading a
scenario (which asks the registry for ``planner.kind``) loads no planner. The
composite stacks get their parts through constructors: ``auto`` builds one
perception, its DMPC half on it, the radio memory the MP-CDE half plans
against (:class:`mpcde.onboard.auto.RadioMemory`), then the MP-CDE half with
that memory as its neighbour source; ``minco_comm`` builds its radio plan
memory first and hands it to the MP-CDE planner it wraps.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from mpcde.config.stack_rules import (
    check_admm, check_denied_ground_clearance, check_dmpc_round, check_flight_levels, check_mlr,
)
from mpcde.stacks.registry import AgentContext, Derivation, Stack, Uses

__all__ = ["BUILTIN", "DEFAULT_KIND", "DEFAULT_KIND_WITHOUT_CAMERAS", "PAPER_PRESET"]


def _placeholder(ctx: AgentContext) -> Any:
    from mpcde.onboard.placeholder import Agent

    p = ctx.config.planner
    return Agent(ctx.drone_id, np.asarray(ctx.goal_world, float), p.line_speed_mps, p.start_delay_s)


def _denied(ctx: AgentContext) -> Any:
    from mpcde.onboard.denied import DeniedAgent

    cfg = ctx.config
    return DeniedAgent(ctx.drone_id, ctx.goal_world, cfg.denied, cfg.perception, budget=ctx.budget, swarm_size=len(ctx.goals_world))


def _dmpc_agent(ctx: AgentContext, dmpc: Any, perception: Any = None, fusion: Any = None) -> Any:
    """The DMPC agent of ``ctx``'s drone with settings ``dmpc`` (formation offsets from the goals when configured)."""
    from mpcde.onboard.dmpc import DmpcAgent

    cfg, i = ctx.config, ctx.drone_id
    goals = np.asarray(ctx.goals_world, float)
    offsets = {j: goals[j] - goals[i] for j in range(len(goals)) if j != i} if dmpc.formation_from_goals else None
    return DmpcAgent(
        i, goals[i], dmpc, cfg.planner.start_delay_s, offsets, ctx.obstacles, cfg.physics.quadrotor.robot_radius_m,
        cfg.perception, perception, fusion, ctx.budget,
    )  # fmt: skip


def _dmpc(ctx: AgentContext) -> Any:
    return _dmpc_agent(ctx, ctx.config.dmpc)


def _auto(ctx: AgentContext) -> Any:
    from mpcde.onboard.auto import AutoAgent, RadioMemory
    from mpcde.onboard.denied import DeniedAgent
    from mpcde.onboard.perception import onboard_perception

    cfg = ctx.config
    # one perception for both halves; denied.perceive_neighbours: false turns it off for both
    perception, _ = onboard_perception(cfg.denied.perceive_neighbours, cfg.perception)
    comm = _dmpc_agent(ctx, replace(cfg.dmpc, perceive_neighbours=perception is not None), perception, cfg.auto.fusion)
    memory = RadioMemory(cfg.auto, comm, perception)
    denied = DeniedAgent(
        ctx.drone_id, ctx.goal_world, cfg.denied, cfg.perception, perception, ctx.budget, swarm_size=len(ctx.goals_world),
        neighbour_source=memory,
    )  # fmt: skip
    return AutoAgent(cfg.auto, comm, denied, memory)


def _mlr(ctx: AgentContext) -> Any:
    from mpcde.onboard.mlr import MlrAgent

    cfg = ctx.config
    planner = cfg.mlr.planner_config(len(ctx.goals_world), cfg.world.arena_size_m)
    return MlrAgent(ctx.drone_id, ctx.goals_world, planner, cfg.planner.start_delay_s, cfg.mlr.ignore_message_loss)


def _admm(ctx: AgentContext) -> Any:
    from mpcde.onboard.admm import AdmmAgent

    cfg, p = ctx.config, ctx.config.planner
    return AdmmAgent(ctx.drone_id, ctx.goals_world, cfg.admm, cfg.world.arena_size_m, p.start_delay_s, p.line_speed_mps)


def _minco_comm(ctx: AgentContext) -> Any:
    from mpcde.onboard.minco_comm import MincoCommAgent

    return MincoCommAgent(ctx.drone_id, ctx.goal_world, ctx.config.denied, budget=ctx.budget)


def _checks(*rules: Any) -> Any:
    """One load-time check running ``rules`` in order."""

    def check(cfg: Any, starts: np.ndarray, goals: np.ndarray) -> None:
        for rule in rules:
            rule(cfg, starts, goals)

    return check


_DENIED_CHECKS = _checks(check_denied_ground_clearance, check_flight_levels)
"""The load-time rules of a stack that flies the denied planner: starts and goals clear of the ground, the levels."""


def _commit_obstacle_range_m(cfg: Any) -> float:
    """max(3.0, sqrt(2) v_max_mps K h + robot radius + obstacle margin) [m]: the reach of a DMPC plan flown to its halt
    unrevised (``dmpc.commit_when_unheard``), over which every obstacle needs its plane
    (docs/results/comm_safety.md#the-mechanism-dmpccommit_when_unheard-default-on-mpcdeonboarddmpcpy)."""
    d, qp = cfg.dmpc, cfg.dmpc.qp
    inflation = cfg.physics.quadrotor.robot_radius_m + d.obstacle_margin_m
    return max(type(d)().obstacle_range_m, float(np.sqrt(2.0) * qp.limits.v_max_mps * qp.horizon_s) + inflation)


_COMMIT_RANGE = Derivation(
    "dmpc.obstacle_range_m", "sqrt(2) dmpc.qp.limits.v_max_mps K h + the inflation (dmpc.commit_when_unheard: true)",
    _commit_obstacle_range_m, lambda c: c.dmpc.commit_when_unheard,
)


def _dmpc_formation(cfg: Any) -> bool:
    return bool(cfg.dmpc.formation_from_goals)


SAFE_PRESET = {"denied.fresh_path_age_s": 1.0}
"""``denied``'s preset: MP-CDE with look before moving (:mod:`mpcde.onboard.denied.look`) at the age its forest
sweep flew, the mechanism the held-out geometries favoured (docs/results/denied_default.md#the-decision). The
section's own defaults stay the paper's, so ``auto``'s fallback and ``minco_comm``, measured that way, fly as before."""

PAPER_PRESET = {
    "denied.fresh_path_age_s": float("inf"),
    "denied.flight_level_spacing_m": float("inf"),
    "denied.yaw.tracking_sweep_deg": 60.0,
    "denied.yaw.tracking_sweep_period_s": 2.1,
    "denied.yaw.free_max_age_s": 1.0,
}
"""``mpcde_paper``'s preset: MP-CDE (Alg. 1, Table I) as this package's reproductions of its Fig. 6, Table III
and Fig. 10 fly it, pinned so that a change of the ``denied`` defaults does not move them. Off: the two safety
mechanisms the package adds (look before moving, flight levels). Kept, and named here so that they stay what the
reproductions flew: two readings of the paper this package made, the tracking mode's swing about the direction of
travel (+-60 deg every 2.1 s; ``denied.yaw.tracking_sweep_deg: 0`` is the paper's straight tracking mode, in which
two drones converging side by side never enter each other's view) and the ageing of verified-free space after 1 s
in Eq. 1's safe segment ("temporally validated by the perception pipeline")."""

BUILTIN: tuple[Stack, ...] = (
    Stack(
        "placeholder", _placeholder, "a blind minimum-jerk straight line to the goal", kind="min_jerk_line",
    ),
    Stack(
        "denied", _denied, "MP-CDE without radio: own detector, tracks, active yaw, A* + MINCO; looks before moving",
        kind="mpcde", uses=Uses(cameras="required"), section="denied", check=_DENIED_CHECKS,
        speed_fields=("denied.limits.v_max_mps",), preset=SAFE_PRESET,
    ),
    Stack(
        "mpcde_paper", _denied, "denied as MP-CDE publishes it: without look before moving or flight levels",
        uses=Uses(cameras="required"), section="denied", check=_DENIED_CHECKS, speed_fields=("denied.limits.v_max_mps",),
        preset=PAPER_PRESET,
    ),
    Stack(
        "comm", _dmpc, "distributed MPC (OSQP) on the plans neighbours broadcast, known obstacles", kind="dmpc",
        uses=Uses(cameras="optional", radio=True, known_obstacles=True), section="dmpc", check=check_dmpc_round,
        speed_fields=("dmpc.qp.limits.v_max_mps",), flies_formation=_dmpc_formation, derived=(_COMMIT_RANGE,),
    ),
    Stack(
        "auto", _auto, "comm, with tracks for stale plans; denied when the radio falls silent",
        uses=Uses(cameras="required", radio=True, known_obstacles=True), section="auto",
        check=_checks(check_dmpc_round, _DENIED_CHECKS), speed_fields=("denied.limits.v_max_mps", "dmpc.qp.limits.v_max_mps"),
        flies_formation=_dmpc_formation, derived=(_COMMIT_RANGE,),
    ),
    Stack(
        "mlr", _mlr, "MLR-DMPC: compute units on the first drones, message-loss recovery; no obstacles",
        uses=Uses(radio=True, joint=True), section="mlr", check=check_mlr, cruise_speed=False,
    ),
    Stack(
        "admm", _admm, "formation DMPC solved by ADMM across neighbours; no obstacles",
        uses=Uses(radio=True, joint=True), section="admm", check=check_admm, flies_formation=lambda cfg: True,
        derived=(
            Derivation(
                "radio.rate_hz", "2 x the ADMM iterations per step / admm.step_s (admm.radio_rate_from_step: true)",
                lambda c: c.admm.radio_rate_hz, lambda c: c.admm.radio_rate_from_step,
            ),
        ),
    ),
    Stack(
        "minco_comm", _minco_comm, "the denied planner on radio plans, heading along travel (EGO-Swarm analogue)",
        uses=Uses(cameras="optional", radio=True), section="denied", check=check_denied_ground_clearance,
        speed_fields=("denied.limits.v_max_mps",),
    ),
)  # fmt: skip
"""The built-in stacks, in the order ``--help`` lists them."""

DEFAULT_KIND = "auto"
"""The ``planner.kind`` of a scenario that names none: the package's headline stack, DMPC over the radio that falls
back to MP-CDE on its cameras. Chosen on the forest swarm's kept stores: it arrives where MP-CDE as published,
on the same seeds, does not (docs/results/denied_default.md#the-decision-rule)."""
DEFAULT_KIND_WITHOUT_CAMERAS = "dmpc"
"""The ``planner.kind`` of a scenario that names none and renders no camera (``run.cameras: false``): ``auto``
needs its cameras, the comm stack flies the same radio without them."""
