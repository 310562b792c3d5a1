"""The turn once round and the way out of the obstacle band, a component of the denied agent.

Two situations leave a drone where no plan keeping the obstacle band
(0.75 clearance_m) can start:

* a halting hand-over (``auto.handover: halt``): the DMPC half brought the
  drone to rest where its last plan halted, which may lie inside the denied
  stack's band (DMPC keeps its own, smaller obstacle margin);
* a stop (the agent's brake) that ended inside the band.

In both the drone hovers and turns the camera once round at the yaw-rate
limit (:meth:`RestEscape.begin`), so that the neighbours about it become
tracks before it moves; until the reference first leaves the band, a plan may
then come no closer to the obstacles than the hover point is
(:meth:`RestEscape.floor`, fixed at the first plan from it, to half a voxel).
Not in MP-CDE. A drone that entered the band in flight gets no such rule
(tried and dropped: docs/results/radio_outage.md#tried-and-dropped).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from mpcde.onboard.denied.agent import DeniedAgent

__all__ = ["RestEscape"]


class RestEscape:
    """The camera's turn once round and the band escape after it, for one drone.

    Args:
        yaw_rate_max_radps: the turn's rate [rad/s]: one revolution takes 2 pi / rate.
        half_voxel_m: the ESDF's resolution the floor is lowered by [m].
    """

    def __init__(self, yaw_rate_max_radps: float, half_voxel_m: float) -> None:
        self.rate_radps = float(yaw_rate_max_radps)
        self.half_voxel_m = float(half_voxel_m)
        self.turn: tuple[float, float, float] | None = None  # (start [s], start yaw [rad], end [s]) of the turn
        self.escaping = False  # leaving the band the drone was handed over in or came to rest in
        self.floor_m: float | None = None  # fixed at the first plan from the hover point

    def holds(self, agent: DeniedAgent, t: float) -> bool:
        """Whether the turn is due or on at ``t`` [s], or begins now because the agent's stop ended inside the
        obstacle band (:meth:`resting_in_band`): the agent plans nothing meanwhile. When the turn ends, the agent's
        trajectory is dropped (it hovers where it turned) and its heading continues from where the turn left it."""
        if self.turn is not None:
            return self._settle(agent, t)
        if not self.resting_in_band(agent, t):
            return False
        agent.stats.rest_escapes += 1
        agent.turn_once_round(t, agent.state_at(t)[0], agent.heading.yaw)
        return True

    def resting_in_band(self, agent: DeniedAgent, t: float) -> bool:
        """Whether the agent's stop (its brake) has ended by ``t`` [s] with the drone inside the obstacle band
        (0.75 clearance_m on the map's newest clearance) and no escape under way.

        From there every plan starts inside the band, so the agent refuses them all and the drone would hover
        until the map changed (docs/results/radio_outage.md#a-drone-at-rest-inside-the-band-turn-then-escape).
        Only a drone at rest qualifies: the same rule for plans begun inside the band in flight was tried and dropped.
        """
        stop = agent.trajectory
        if not agent.braking or self.escaping or stop is None or t < stop.t0_s + stop.total_duration - 1e-9:
            return False
        rest = stop.pos(np.array([stop.total_duration]))
        return bool(agent.map.clearance(rest)[0] < agent.band_m)

    def begin(self, time_s: float, yaw: float) -> tuple[float, float]:
        """Schedule the turn from ``time_s`` [s] and ``yaw`` [rad], with the escape after it; returns its start and end [s]."""
        self.escaping, self.floor_m = True, None
        t0 = float(time_s)
        self.turn = (t0, float(yaw), t0 + 2.0 * np.pi / self.rate_radps)
        return t0, self.turn[2]

    def cancel(self) -> None:
        """Drop the turn and the escape (another stack's reference is taken over)."""
        self.turn, self.escaping = None, False

    def pending(self, t: float) -> bool:
        """Whether a turn is due or on at ``t`` [s] (scheduled and not ended): nothing is planned meanwhile."""
        return self.turn is not None and t < self.turn[2] - 1e-9

    def turning(self, agent: DeniedAgent, t: float) -> bool:
        """Whether the turn itself is on at ``t`` [s] (started, not ended), for the agent's reference; a turn that has
        ended by ``t`` is finished first, as at a frame (:meth:`holds`), so that the reference after it is the hover."""
        return self._settle(agent, t) and t >= self.turn[0] - 1e-9

    def _settle(self, agent: DeniedAgent, t: float) -> bool:
        """Whether a turn is due or on at ``t`` [s]; one that has ended by ``t`` is finished: the agent's trajectory
        dropped, its heading continued from a full revolution past the turn's start yaw."""
        if self.turn is None:
            return False
        if self.pending(t):
            return True
        _, yaw0, _ = self.turn
        self.turn = None
        agent.trajectory, agent.braking = None, False
        agent.heading.restart(yaw0 + 2.0 * np.pi, t)
        return False

    def turn_yaw(self, t: float) -> tuple[float, float]:
        """(yaw [rad], yaw rate [rad/s]) of the turn at ``t`` [s]."""
        t0, yaw0, _ = self.turn
        return yaw0 + self.rate_radps * (t - t0), self.rate_radps

    def floor(self, distance: Callable[[np.ndarray], np.ndarray], pos_world: np.ndarray, band_m: float) -> float | None:
        """The obstacle clearance [m] a plan from ``pos_world`` (3,) [m] must keep while escaping; None (the band) otherwise.

        ``distance`` maps (n, 3) points [m] to their obstacle distance (n,) [m]. The escape ends, for good,
        once the drone is out of the band ``band_m`` [m].
        """
        if not self.escaping:
            return None
        d = float(distance(np.asarray(pos_world, float)[None])[0])
        if d >= band_m:
            self.escaping = False
            return None
        if self.floor_m is None:  # fixed at the first plan from the hover point: no ratchet inwards
            self.floor_m = d - self.half_voxel_m
        return self.floor_m
