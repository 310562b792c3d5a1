"""MP-CDE's paper reproduction, reported from sweep stores (``mpcde paper``; issue 28).

:mod:`~mpcde.paper.table3` (Table III), :mod:`~mpcde.paper.summary` (the paper's Sec. V-B figures beside ours),
:mod:`~mpcde.paper.goals` (issue 28's goals, met or missed), :mod:`~mpcde.paper.swarm_modes` (the denied swarm's
yaw modes and contacts per cell), :mod:`~mpcde.paper.ceiling` (the most any yaw could see along a flight's path),
:mod:`~mpcde.paper.stores` (reading a store as they do) and :mod:`~mpcde.paper.commands` (the subcommands).
Nothing is imported here: each module loads on first use.
"""
