"""Flight levels, a component of the denied agent (``denied.flight_level_spacing_m``): which goal a replan flies to, in which layer.

With flight levels, drone k of a mission of N cruises at its own altitude
(:func:`mpcde.config.stack_rules.flight_level_m`), so that drones that cannot
see each other do not share a layer. This module holds the rule's state for
one drone (reached its level, released from it) and turns the drone's
position into the goal and the altitude layer of its next replan
(:meth:`FlightLevels.goal_and_layer`); :func:`held_in_layer` applies the layer
to the agent's optimiser and front end. Not in MP-CDE: procedural vertical
separation, the rule of airspace without surveillance.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from mpcde.config.stack_rules import flight_level_m
from planners.path_search import PathSearchConfig
from planners.trajectory_optimizer import TrajectoryOptimizerConfig

__all__ = ["FlightLevels", "held_in_layer"]


def held_in_layer(
    optimizer: TrajectoryOptimizerConfig, search: PathSearchConfig, lo_m: float, hi_m: float, voxel_m: float
) -> tuple[TrajectoryOptimizerConfig, PathSearchConfig]:
    """The optimiser (altitude penalty) and the front end's search held in altitudes [lo_m, hi_m] [m].

    The search's bounds are widened by a voxel, so that the start's own voxel stays in the layer.
    """
    optimizer = dataclasses.replace(optimizer, altitude_band_m=(lo_m, hi_m))
    search = dataclasses.replace(search, min_altitude_m=max(0.0, lo_m - voxel_m), max_altitude_m=hi_m + voxel_m)
    return optimizer, search


@dataclass
class FlightLevels:
    """One drone's flight level and where it is in the climb-cruise-release sequence.

    Args:
        goal_world: (3,) the mission's goal [m].
        level_m: this drone's level [m] (fixed by its first pose estimate).
        spacing_m: s, the levels' vertical spacing [m]; the level is held within s / 8.
        release_m: horizontal distance [m] to the goal within which the drone leaves its level, for good.
    """

    goal_world: np.ndarray
    level_m: float
    spacing_m: float
    release_m: float
    reached: bool = False  # came within s / 8 of the level: from then on held there, for good
    released: bool = False  # left the level for the goal (within release_m of it), for good

    @classmethod
    def for_drone(
        cls, drone_id: int, swarm_size: int, start_world: np.ndarray, goal_world: np.ndarray, spacing_m: float, release_m: float
    ) -> FlightLevels:
        """Drone ``drone_id`` of ``swarm_size``'s level about the mean of its start and goal altitudes
        (:func:`mpcde.config.stack_rules.flight_level_m`); the id and the size are the mission's assignment."""
        centre = 0.5 * (float(start_world[2]) + float(goal_world[2]))
        return cls(np.asarray(goal_world, float), flight_level_m(centre, drone_id, swarm_size, spacing_m), spacing_m, release_m)

    @property
    def hold_m(self) -> float:
        """b = s / 8 [m], how far from its level a drone counts as at it, and the layer's margin."""
        return self.spacing_m / 8.0

    def goal_and_layer(self, pos_world: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
        """The goal (3,) [m] a replan from ``pos_world`` (3,) [m] flies to, and the layer (lo, hi) [m] it is flown in.

        1. until the drone first comes within b of its level, it climbs (or descends)
           to it where it is: the goal is its own position carried to the level, the
           layer spans its altitude and the level. Climbing in place, before leaving
           the start, no drone crosses another's level on the way (a climb spread along
           the path left two drones 0.2 m apart at 1.58 m, both still between their
           levels 5 s into the flight: docs/results/safety.md#flight-levels);
        2. then it flies to its goal carried to the level, held within b of it;
        3. within ``release_m`` of the goal horizontally it is released, for good: the
           goal itself, the layer down (or up) to the goal's altitude.
        Each layer is widened by b on both sides.
        """
        level, b, z = self.level_m, self.hold_m, float(pos_world[2])
        self.reached = self.reached or abs(z - level) <= b
        if np.linalg.norm(pos_world[:2] - self.goal_world[:2]) <= self.release_m:
            self.released = True
        if self.released:
            heights, goal = [level, z, float(self.goal_world[2])], self.goal_world
        elif self.reached:
            heights, goal = [level], np.array([self.goal_world[0], self.goal_world[1], level])
        else:
            heights, goal = [level, z], np.array([pos_world[0], pos_world[1], level])
        return goal, (min(heights) - b, max(heights) + b)

    def climbed(self, pos_world: np.ndarray) -> bool:
        """Whether a drone not yet at its level is now, at ``pos_world`` (3,) [m], within b of it (replan for the goal)."""
        return not self.reached and abs(float(pos_world[2]) - self.level_m) <= self.hold_m
