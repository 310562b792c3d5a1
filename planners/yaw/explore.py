"""The exploring step shared by the yaw planners: the maximum-reward yaw sequence on the lattice (MP-CDE Eq. 3-5).

Each of the n layers' m candidate yaws is scored by the area of the cells it
would newly see (Eq. 3, rays cast through the map window from the planned
position) and, for MP-CDE, by the visibility of the neighbours not recently
seen (Eq. 4); Dijkstra on the lattice finds the best rate-limited sequence
(Eq. 5). Zhou et al.'s reward is the first term alone with no coverage
window: ``covered`` all False, alpha = 1, beta = 0.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from perception.types import NeighborPrediction, OccupancySnapshot
from planners.yaw.config import YawPlannerConfig
from planners.yaw.coverage import FanGeometry, cast_fans, edge_gains, ray_gains
from planners.yaw.lattice import LatticePath, edge_costs, shortest_path
from planners.yaw.visibility import visibility_rewards

__all__ = ["explore_yaws"]


def explore_yaws(
    cfg: YawPlannerConfig,
    fan: FanGeometry,
    yaw: float,
    times: np.ndarray,
    positions: np.ndarray,
    snapshot: OccupancySnapshot,
    covered: np.ndarray,
    unseen: Sequence[NeighborPrediction],
    alpha: float,
    beta: float,
) -> tuple[np.ndarray, LatticePath]:
    """Yaws (n + 1,) [rad] from ``yaw`` over layer ``times`` (n + 1,) [s] at ``positions`` (n + 1, 3) [m], and the path.

    ``covered``: the padded cell mask of space already seen within the window W (Eq. 3's subtraction);
    ``unseen``: the neighbours of A minus V whose visibility Eq. 4 rewards; ``alpha``, ``beta``: Eq. 5's weights.
    """
    m, q = cfg.n_candidates, cfg.max_hop
    cast = cast_fans(snapshot, positions[1:], fan.azimuths(yaw), fan.ranges_m)
    gains, e_max = edge_gains(ray_gains(cast, covered, fan.areas_m2), fan, m, q)
    e = gains / e_max  # Eq. 3, normalised to [0, 1]
    candidate_yaws = yaw + np.arange(m) * cfg.candidate_spacing_rad
    v = visibility_rewards(positions[1:], times[1:], candidate_yaws, unseen, cfg)  # Eq. 4, in [0, 1]
    path = shortest_path(edge_costs(e, v, alpha, beta, cfg.turn_penalty))  # Eq. 5
    return yaw + cfg.candidate_spacing_rad * np.concatenate([[0.0], np.cumsum(path.hops)]), path
