"""The process's floating-point profile: one instruction set for every library, so a seed flies alike on any x86-64 CPU.

Why. A perceiving flight is chaotic: a last-bit difference in one BLAS call
moves a track by a nanometre, the yaw planner's argmax flips a few frames
later, and the flight diverges. The libraries a flight uses pick their
kernels by the CPU they run on: OpenBLAS a kernel per core type (SkylakeX,
Haswell, Zen), numpy a SIMD level (x86-64-v3 or v4), torch's ATen and oneDNN
an ISA, numba the host CPU, and ``perception.detector_precision: auto``
bfloat16 where the CPU computes it natively. So the same commit, seeds and
locked packages fly differently on two machines, and on one machine between
its native kernels and the x86-64-v3 ones (docs/results/reproducibility.md).

What. ``MPCDE_NUMERICS`` (environment) names the profile:

* ``portable`` (the default): every library at x86-64-v3 (AVX2, FMA), the
  level nearly every x86-64 CPU since 2013 has: OpenBLAS's Haswell kernels,
  numpy's dispatch without its v4 (AVX-512) targets, ATen and oneDNN capped at
  AVX2 (so ``detector_precision: auto`` keeps float32, as on a CPU without
  native bfloat16), numba compiling for Haswell. A flight then computes what it
  computes on an AVX2 machine. Cost on this project's 2-core AVX-512 machine:
  benchmarks/bench_numerics.py.
* ``native``: each library's own choice for this CPU (fastest; per-seed
  results hold only on the same kind of CPU).

How. :func:`apply` sets the libraries' own variables (:data:`X86_V3`, each only
where unset, so one can still be overridden) in ``os.environ``. They take effect
in a process only if set before the library loads, which is why ``mpcde``
applies them on import, before anything imports numpy, and why child processes
(sweep workers, render workers) started afterwards inherit them. A process that
loaded numpy before ``import mpcde`` (a notebook, pytest) keeps its native
kernels for itself; :func:`describe` reports what is in effect, not what was
asked, and every flight records it (``metrics.json``, ``numerics``). On a CPU
that is not x86-64, or lacks AVX2 / FMA / BMI2, the profile sets nothing.
"""

from __future__ import annotations

import os
import platform
import sys

__all__ = ["DEFAULT", "PROFILES", "VARIABLE", "X86_V3", "apply", "cpu_flags", "describe", "mismatch", "requested"]

VARIABLE = "MPCDE_NUMERICS"
PROFILES = ("portable", "native")
DEFAULT = "portable"

X86_V3: dict[str, str] = {
    "OPENBLAS_CORETYPE": "Haswell",  # numpy's and scipy's OpenBLAS: one kernel family whatever the core
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",  # numpy's dispatch stops at x86-64-v3
    "ATEN_CPU_CAPABILITY": "avx2",  # torch's vectorised elementwise kernels (the detector's activations)
    "ONEDNN_MAX_CPU_ISA": "AVX2",  # torch's convolutions; no native bfloat16 below AVX512_CORE_BF16
    "NUMBA_CPU_NAME": "haswell",  # the map's and the controller's compiled kernels ...
    "NUMBA_CPU_FEATURES": "+avx2,+fma,+bmi2",  # ... with Haswell's features, not the host's (numba's default)
}
"""The variables of the ``portable`` profile, each the library's own (its documentation names it)."""


def requested(environ: os._Environ[str] | dict[str, str] | None = None) -> str:
    """The profile ``MPCDE_NUMERICS`` asks for (``DEFAULT`` when unset).

    Raises:
        mpcde.errors.ConfigError: a value outside :data:`PROFILES`.
    """
    env = os.environ if environ is None else environ
    value = env.get(VARIABLE, DEFAULT)
    if value not in PROFILES:
        from mpcde.errors import ConfigError

        raise ConfigError(VARIABLE, value, f"allowed {' or '.join(repr(p) for p in PROFILES)} (environment)")
    return value


def apply(environ: os._Environ[str] | dict[str, str] | None = None, machine: str | None = None, cpuinfo: str | None = None) -> bool:
    """Set :data:`X86_V3` where unset if the profile is ``portable`` on an x86-64-v3 CPU; True if it did.

    An invalid ``MPCDE_NUMERICS`` sets nothing here (importing must not fail);
    the command line refuses it with one line (:func:`requested`). Nor does a
    CPU without AVX2, FMA and BMI2 (or whose flags cannot be read): numba and
    OpenBLAS told "Haswell" would run instructions it does not have.

    Args:
        machine: ``platform.machine()`` when None.
        cpuinfo: text of ``/proc/cpuinfo`` (read when None).
    """
    env = os.environ if environ is None else environ
    if env.get(VARIABLE, DEFAULT) != "portable" or (machine or platform.machine()).lower() not in ("x86_64", "amd64"):
        return False
    if not _has_x86_64_v3(cpuinfo):
        return False
    for key, value in X86_V3.items():
        env.setdefault(key, value)
    return True


def cpu_flags(cpuinfo: str | None = None) -> frozenset[str]:
    """The flags of every ``flags`` line of ``cpuinfo`` (Linux ``/proc/cpuinfo`` when None; empty where unreadable).

    The detector's ``native_bfloat16`` parses the same lines itself: ``perception`` may not import ``mpcde``.
    """
    if cpuinfo is None:
        try:
            with open("/proc/cpuinfo") as f:
                cpuinfo = f.read()
        except OSError:
            return frozenset()
    flags: set[str] = set()
    for line in cpuinfo.splitlines():
        if line.startswith("flags"):
            flags.update(line.split(":", 1)[-1].split())
    return frozenset(flags)


def _has_x86_64_v3(cpuinfo: str | None = None) -> bool:
    """Whether the CPU flags include AVX2, FMA and BMI2, the core of x86-64-v3."""
    return {"avx2", "fma", "bmi2"} <= cpu_flags(cpuinfo)


def describe() -> dict[str, str | bool | dict[str, str | None] | None]:
    """What this process computes with: numpy and OpenBLAS read from the libraries, the others' variables.

    Returns:
        ``profile`` (asked for), ``effective`` (``portable`` when numpy and
        OpenBLAS run at x86-64-v3 and torch's and numba's variables, where set,
        hold the profile's values; ``native`` when none of that holds;
        ``mixed`` otherwise, e.g. numpy loaded before ``import mpcde``; a CPU
        without AVX-512 may read ``portable`` under ``native``: its own
        choices are the profile's), ``machine``, ``numpy_v4`` (numpy
        dispatches to x86-64-v4; None off x86-64 or before numpy loads),
        ``openblas_core`` (numpy's OpenBLAS kernel family; None if unknown) and
        ``pins`` (each variable of :data:`X86_V3` as this process's environment
        holds it; torch and numba read theirs when they load). The same in
        every process of a run whatever it happened to import, so two flights
        of one task record the same.
    """
    numpy_v4 = openblas_core = None
    if "numpy" in sys.modules:
        try:
            from numpy._core._multiarray_umath import __cpu_features__

            numpy_v4 = bool(__cpu_features__.get("X86_V4")) if "X86_V4" in __cpu_features__ else None
        except ImportError:  # another numpy layout: unknown
            numpy_v4 = None
        openblas_core = _openblas_core()
    pins = {key: os.environ.get(key) for key in X86_V3}
    # numpy and OpenBLAS as read; torch and numba by their variables where set (unset: unknown, for a CPU
    # without AVX-512 chooses AVX2 itself)
    checks = [numpy_v4 is False if numpy_v4 is not None else None,
              openblas_core == X86_V3["OPENBLAS_CORETYPE"] if openblas_core is not None else None,
              *(pins[key] == value if pins[key] is not None else None for key, value in X86_V3.items()
                if key not in ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES"))]  # fmt: skip
    known = [c for c in checks if c is not None]
    effective = "portable" if known and all(known) else "native" if not any(known) else "mixed"
    return {"profile": os.environ.get(VARIABLE, DEFAULT), "effective": effective, "machine": platform.machine(),
            "numpy_v4": numpy_v4, "openblas_core": openblas_core, "pins": pins}  # fmt: skip


def mismatch(described: dict | None = None, cpuinfo: str | None = None) -> str | None:
    """One line saying why this process is not at the portable profile it asks for, or None.

    None also where nothing was asked (``native``) or nothing can be (not
    x86-64, or a CPU without x86-64-v3, whose flags ``cpuinfo`` gives; read
    from ``/proc/cpuinfo`` when None).
    """
    d = describe() if described is None else described
    if d["profile"] != "portable" or d["machine"].lower() not in ("x86_64", "amd64") or d["effective"] == "portable":
        return None
    if not _has_x86_64_v3(cpuinfo):  # nothing was set: the CPU cannot run the profile
        return None
    return (f"{VARIABLE}=portable, but this process computes with numerics {d['effective']!r} (numpy v4 {d['numpy_v4']}, "
            f"OpenBLAS {d['openblas_core']}): numpy loaded before `import mpcde`, or a pin was overridden; "
            "its flights will not repeat on another machine (docs/design.md section 15)")  # fmt: skip


def _openblas_core() -> str | None:
    """The kernel family numpy's bundled OpenBLAS runs (``scipy_openblas_get_corename64_``), None if not found."""
    import ctypes

    try:
        with open("/proc/self/maps") as maps:  # address perms offset dev inode [path, which may hold spaces]
            fields = [ln.rstrip("\n").split(maxsplit=5) for ln in maps if "openblas" in ln.lower() and "numpy" in ln]
    except OSError:
        return None
    paths = sorted({f[5] for f in fields if len(f) == 6 and not f[5].endswith("(deleted)")})
    for path in paths:
        try:
            lib = ctypes.CDLL(path)
        except OSError:
            continue
        for name in ("scipy_openblas_get_corename64_", "openblas_get_corename64_", "openblas_get_corename"):
            fn = getattr(lib, name, None)
            if fn is not None:
                fn.restype = ctypes.c_char_p
                name = fn()
                return name.decode() if name else None
    return None
