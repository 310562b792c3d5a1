"""Keep large CPU tensor buffers in the heap between detector calls (glibc only).

Every :meth:`~perception.detector.detector.DroneDetector.detect` call allocates
a handful of multi-megabyte tensors: the encoded input (6 frames x 4 channels
x 320 x 240 float32 = 7.4 MB) and the early activations. glibc serves any
block above ``M_MMAP_THRESHOLD`` (128 kB at start, adapting up to 32 MB only
after frees) with a fresh ``mmap`` and returns it with ``munmap`` on free, so
each call page-faults its buffers in again (measured: docs/results/detector.md#glibc-allocation-thresholds).
This is the CPU tuning the PyTorch performance guide recommends (a caching
allocator or glibc's mmap / trim thresholds).

:func:`keep_large_allocations` raises the mmap threshold to
``MMAP_THRESHOLD_BYTES`` and the trim threshold to ``TRIM_THRESHOLD_BYTES`` with
``mallopt`` for the whole process: freed buffers stay in the heap for reuse (up
to the trim threshold) instead of going back to the kernel. On a libc without
``mallopt`` (musl, macOS) it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util

__all__ = ["MMAP_THRESHOLD_BYTES", "TRIM_THRESHOLD_BYTES", "keep_large_allocations"]

MMAP_THRESHOLD_BYTES = 64 * 1024 * 1024
"""Blocks below this come from the heap, not a fresh mmap [bytes]."""

TRIM_THRESHOLD_BYTES = 256 * 1024 * 1024
"""Free heap memory kept before it is trimmed back to the kernel [bytes]."""

_M_TRIM_THRESHOLD = -1  # glibc malloc.h
_M_MMAP_THRESHOLD = -3
_applied: bool | None = None


def keep_large_allocations() -> bool:
    """Apply the thresholds once per process; True when glibc accepted them."""
    global _applied
    if _applied is None:
        _applied = False
        name = ctypes.util.find_library("c")
        try:
            libc = ctypes.CDLL(name) if name else None
            mallopt = getattr(libc, "mallopt", None)
            if mallopt is not None:
                ok_mmap = mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES)
                ok_trim = mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES)
                _applied = bool(ok_mmap) and bool(ok_trim)
        except OSError:  # pragma: no cover - no loadable C library
            _applied = False
    return _applied
