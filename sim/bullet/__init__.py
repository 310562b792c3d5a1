"""PyBullet, imported without its build-time banner.

Importing ``pybullet`` prints ``pybullet build time: ...`` on the process's
stderr (file descriptor 2, from C, so ``sys.stderr`` cannot catch it). A user
who gets one line for an error must not get that line too, so every module of
ours imports PyBullet from here: the first import runs with descriptor 2
pointed at the null device, and later ones find it in ``sys.modules``.

:mod:`sim.bullet.scene` is what every PyBullet client of ours (the physics
world and each render client) builds its bodies from.
"""

from __future__ import annotations

import os
import sys
from types import ModuleType

__all__ = ["pb"]


def _import_quietly() -> ModuleType:
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stderr.flush()
    saved = os.dup(2)
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(devnull, 2)
        finally:
            os.close(devnull)
        import pybullet
    finally:
        os.dup2(saved, 2)
        os.close(saved)
    return pybullet


pb = _import_quietly()
