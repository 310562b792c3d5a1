"""perception: onboard sensing (detector, back-projection, map, tracks).

Imports :mod:`sim.types` only (and :mod:`sim.kernel_cache`, here). Sees camera frames without segmentation, the
drone's own pose estimate, never another drone's ground truth.
"""

from sim.kernel_cache import use_versioned_cache

use_versioned_cache()  # before any kernel of this package is compiled (sim/kernel_cache.py)
