"""sim: the simulated world (PyBullet scene, quadrotor physics, cameras, radio).

Imports no other package of mpcde. Onboard code sees only the types in
:mod:`sim.types` that a real drone would have (its own camera frames and pose
estimate, its radio inbox); ground truth stays in :mod:`sim.ground_truth`.
"""

from sim.kernel_cache import use_versioned_cache

use_versioned_cache()  # before any kernel of this package is compiled (sim/kernel_cache.py)
