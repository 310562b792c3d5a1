"""OSQP's compiled solver object, called directly by the DMPC QPs (:mod:`planners.dmpc.qp`, :mod:`planners.dmpc.admm.local_qp`).

osqp 1.x keeps its compiled solver in ``OSQP._solver``. The Python wrapper's
per-call work around it (clipping the bounds again, caching data for
derivatives, building result namespaces) costs more than a warm-started solve
of these sizes (docs/results/dmpc_qp.md#smaller-figures-from-qppy-and-samplingpy), so the QPs call the compiled object
with the arguments the wrapper would pass. :func:`solver_core` returns it, or,
for an osqp without one, :class:`WrapperCore`: the same calls through the
public wrapper. Bounds given to either are already within +-OSQP_INFTY.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import osqp

__all__ = ["WrapperCore", "solver_core"]

_CALLS = ("update_data_vec", "update_data_mat", "warm_start", "solve")


def solver_core(solver: osqp.OSQP) -> Any:
    """The object whose ``update_data_vec``, ``update_data_mat``, ``warm_start``, ``solve``, ``info`` and ``solution`` the QPs use."""
    core = getattr(solver, "_solver", None)
    if core is not None and all(hasattr(core, f) for f in _CALLS):
        return core
    return WrapperCore(solver)


class WrapperCore:
    """The compiled solver's calls, made through osqp's public wrapper (an osqp with no ``_solver``)."""

    def __init__(self, solver: osqp.OSQP) -> None:
        self._solver = solver
        self._res = None

    def update_data_vec(self, q: np.ndarray, l: np.ndarray | None = None, u: np.ndarray | None = None) -> None:
        kwargs = {"q": q}
        if l is not None:
            kwargs.update(l=l, u=u)
        self._solver.update(**kwargs)

    def update_data_mat(self, P_x: np.ndarray | None, P_i: None, A_x: np.ndarray | None, A_i: None) -> None:
        kwargs = {k: v for k, v in (("Px", P_x), ("Ax", A_x)) if v is not None}
        if kwargs:
            self._solver.update(**kwargs)

    def warm_start(self, x: np.ndarray, y: np.ndarray) -> None:
        self._solver.warm_start(x=x, y=y)

    def solve(self) -> None:
        self._res = self._solver.solve(raise_error=False)

    @property
    def info(self):  # osqp's info namespace
        return self._res.info

    @property
    def solution(self):  # osqp's result (x, y)
        return self._res
