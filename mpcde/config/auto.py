"""The ``auto:`` section of a scenario: the mode switch and the plan/track fusion of the ``auto`` stack."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from mpcde.errors import ConfigError
from sim.checks import require_instance, require_one_of, require_positive

__all__ = ["HANDOVERS", "AutoAgentConfig", "FusionConfig"]

HANDOVERS = ("continue", "halt")
"""``auto.handover``: how the denied half takes over when the radio goes out (:class:`AutoAgentConfig`)."""


@dataclass(frozen=True)
class FusionConfig:
    """When a plan is stale, and how near a track must be to be that plan's drone.

    Attributes:
        stale_after_s: a plan older than this [s] is stale (chosen: 0.5 s; at
            the 5 Hz radio a plan received in the last round is 0.2 s old plus
            the delay, so two missed rounds in a row make a neighbour stale;
            with 20 % Bernoulli loss that happens to 4 % of the neighbour-rounds).
        gate_m: a track within this [m] of a plan's position is that plan's
            drone (chosen: 1.0 m, the tracking score's match radius, several
            times a track's and a plan follower's position error).
    """

    stale_after_s: float = 0.5
    gate_m: float = 1.0

    def __post_init__(self) -> None:
        require_positive("stale_after_s", self.stale_after_s, "s")
        require_positive("gate_m", self.gate_m, "m")



@dataclass(frozen=True)
class AutoAgentConfig:
    """Settings of the ``auto`` agent (the ``auto:`` mapping of a scenario file).

    Attributes:
        radio_silence_s: the radio is out when nothing was sent by anyone
            within this [s] of a round (chosen: 1.0 s, five rounds at 5 Hz:
            with 20 % Bernoulli loss and one neighbour, the chance of five
            losses in a row is 0.03 %, so lossy links do not flip the mode).
        plan_memory_s: in ``denied`` mode the neighbours' last radio plans sent
            within this [s] are still planned against, and pointed at by the
            active yaw planner, fused with the tracks as in comm mode (a plan
            whose drone is tracked gives way to the track); 0 turns the memory
            off (the denied half then sees exactly what pure MP-CDE sees).
            Chosen: 2.0 s. The outage starts with the drones where DMPC left
            them, side by side in the converging swarm, out of each other's
            camera view, where a sideways dodge meets a neighbour the camera
            never saw; the memory covers the first second of denied flight
            after the 1 s of silence, while the active yaw turns the camera to
            the remembered drones and the tracker takes them over
            (docs/results/radio_outage.md#tried-and-dropped).
        fusion: when a neighbour's plan is stale and how near its track must be
            (:class:`mpcde.onboard.fusion.FusionConfig`).
        handover: how the denied half takes over when the radio goes out.
            ``continue``: from the DMPC reference's state, replanning at once.
            ``halt``: the drone first flies its last broadcast DMPC plan to
            that plan's halt (DMPC-Swarm Eq. 13e; it is the plan its
            neighbours remember, and they halt too), turns the camera once
            round there at the yaw-rate limit, so that the neighbours about it
            become tracks, and only then plans; the radio memory
            (``plan_memory_s``) is lengthened by the time from the switch to
            the end of the turn. A plan that does not end at rest
            (``dmpc.qp.terminal_halt: false``) is replaced by the denied half's
            stopping piece. Chosen: ``halt``: it removes the contacts of the
            outage's first seconds that ``continue`` has, for a little more
            mission time (docs/results/radio_outage.md#both-hand-overs-in-one-kept-store).
    """

    radio_silence_s: float = 1.0
    plan_memory_s: float = 2.0
    fusion: FusionConfig = field(default_factory=FusionConfig)
    handover: str = "halt"

    def __post_init__(self) -> None:
        require_positive("radio_silence_s", self.radio_silence_s, "s")
        require_one_of("handover", self.handover, HANDOVERS)
        require_instance("fusion", self.fusion, FusionConfig)
        m = self.plan_memory_s
        if isinstance(m, bool) or not (isinstance(m, (int, float)) and math.isfinite(m) and m >= 0):
            raise ConfigError("plan_memory_s", m, "a finite number >= 0 [s] (0: no radio memory in denied mode)")
