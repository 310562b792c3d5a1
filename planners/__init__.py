"""planners: onboard decisions (yaw, MINCO, DMPC).

Imports :mod:`perception.types` and :mod:`sim.types` only (and :mod:`sim.kernel_cache`, here).
"""

from sim.kernel_cache import use_versioned_cache

use_versioned_cache()  # before any kernel of this package is compiled (sim/kernel_cache.py)
