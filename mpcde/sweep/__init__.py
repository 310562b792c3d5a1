"""Experiments at scale: a sweep file's grid of scenario conditions x seeds, flown on local processes or Ray.

:mod:`~mpcde.sweep.spec` (the sweep file), :mod:`~mpcde.sweep.engine`
(flights as tasks, local and Ray backends), :mod:`~mpcde.sweep.store` (the
resumable JSON-lines results), :mod:`~mpcde.sweep.runner` (``mpcde sweep``),
:mod:`~mpcde.sweep.stats` and :mod:`~mpcde.sweep.report` (``mpcde report``).
"""
