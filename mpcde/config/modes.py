"""The onboard stacks a user picks by name (``mpcde fly --mode``, ``mpcde compare --modes``).

:data:`MODES` maps each command-line mode name to the ``planner.kind`` of the
scenario config (:class:`mpcde.config.scenario.PlannerConfig`) that selects its stack:

* ``placeholder`` -> ``min_jerk_line``: a blind minimum-jerk straight line to the goal;
* ``denied`` -> ``mpcde``: MP-CDE without radio (own detector, tracks, active yaw, MINCO);
* ``comm`` -> ``dmpc``: distributed MPC on plans exchanged over the radio;
* ``auto`` -> ``auto``: ``comm``, falling back to camera tracks and to ``denied`` when the radio fails;
* ``mlr`` -> ``mlr``: MLR-DMPC (DMPC-Swarm): compute units on the first drones, message-loss recovery;
* ``admm`` -> ``admm``: cooperative formation DMPC solved by ADMM across neighbours (Stomberg et al.);
* ``minco_comm`` -> ``minco_comm``: MP-CDE's map and MINCO planner against the plans other drones broadcast
  (the EGO-Swarm analogue, MP-CDE Fig. 6's communicating baseline; :mod:`mpcde.onboard.minco_comm`).

Code that takes a mode validates it against the keys of :data:`MODES` (never
a list of its own), so a stack added here is accepted everywhere at once.
"""

from __future__ import annotations

__all__ = ["MODES"]

MODES: dict[str, str] = {  # --mode -> planner.kind
    "placeholder": "min_jerk_line", "denied": "mpcde", "comm": "dmpc", "auto": "auto", "mlr": "mlr", "admm": "admm",
    "minco_comm": "minco_comm",
}
