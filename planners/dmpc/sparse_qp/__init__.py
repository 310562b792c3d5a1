"""The DMPC QPs on one fixed sparsity pattern for OSQP: the pattern, row layout, compiled core, result.

OSQP factorises a QP's KKT pattern once at setup; later rounds may change only
its values. The per-drone DMPC QP (:mod:`planners.dmpc.qp`), the compute unit's
QP of MLR-DMPC (:mod:`planners.dmpc.mlr.qp`) and the ADMM local QP
(:mod:`planners.dmpc.admm.local_qp`) are therefore laid out once and updated in
place, from these parts:

* :mod:`planners.dmpc.sparse_qp.pattern`: a pattern built block by block, with
  the COO -> CSC map through which a block's new values are written (DMPC, MLR);
* :mod:`planners.dmpc.sparse_qp.qp_layout`: where every row of the DMPC QP's
  constraint matrix sits on it;
* :mod:`planners.dmpc.sparse_qp.osqp_core`: OSQP's compiled solver object,
  called directly (DMPC, ADMM);
* :mod:`planners.dmpc.sparse_qp.qp_result`: what a round returns
  (:class:`DmpcResult`) and raises (:class:`DmpcSolveError` with its
  :class:`QpSnapshot`; DMPC, MLR), re-exported by :mod:`planners.dmpc.qp`.

Nothing is imported here: import from the modules.
"""
