"""The communication-denied stack (MP-CDE): the agent's core and the components composed around it.

* :mod:`~mpcde.onboard.denied.agent`: :class:`DeniedAgent`, MP-CDE's Alg. 1 (perception, map, yaw, A* + MINCO);
* :mod:`~mpcde.onboard.denied.heading`: the active yaw planner on its schedule;
* :mod:`~mpcde.onboard.denied.look`: look before moving;
* :mod:`~mpcde.onboard.denied.levels`: flight levels;
* :mod:`~mpcde.onboard.denied.rest_escape`: the turn once round and the way out of the obstacle band;
* :mod:`~mpcde.onboard.denied.stats`: what the planner did, for metrics.json.
"""

from mpcde.onboard.denied.agent import DeniedAgent
from mpcde.onboard.denied.stats import PlanningStats

__all__ = ["DeniedAgent", "PlanningStats"]
