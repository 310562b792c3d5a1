"""The onboard stacks as plugins: one registry entry each (:mod:`mpcde.stacks.registry`).

A stack written outside this package registers through the ``mpcde.stacks``
entry-point group or :func:`register_stack`, then flies with ``mpcde fly
--mode NAME``, in sweeps, ``compare``, ``report`` and as an environment policy.
The contract and a minimal stack: docs/stacks.md.
"""

from __future__ import annotations

from mpcde.stacks.registry import (
    ENTRY_POINT_GROUP, AgentContext, Derivation, Stack, Uses, get_stack, register_stack, stack_for_kind, stack_of, stacks,
)  # fmt: skip

__all__ = [
    "ENTRY_POINT_GROUP", "AgentContext", "Derivation", "Stack", "Uses", "get_stack", "register_stack", "stack_for_kind",
    "stack_of", "stacks",
]  # fmt: skip
