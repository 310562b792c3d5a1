"""planners: onboard decisions (yaw, MINCO, DMPC).

Imports :mod:`perception.types` and :mod:`sim.types` only.
"""
