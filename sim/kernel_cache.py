"""Where numba caches the project's compiled kernels: a folder named after their source, so an edit recompiles them.

Numba's on-disk cache (``@njit(cache=True)``) checks only the source file of
the function it caches. A cached kernel that calls a kernel of another file
keeps the callee's old machine code after that file changes: in this project
``planners/trajectory_variables.py`` calls ``planners/trajectory_penalty.py``,
and a checkout that has compiled the former goes on flying the old penalty
after the penalty changes (docs/results/minco.md#a-stale-compiled-penalty-numbas-cache-and-kernels-of-other-files-2026-11-26-seventh-sitting).

:func:`use_versioned_cache` therefore points numba's cache at
``<base>/kernels-<digest>``, where the digest is a SHA-256 of every module of
the project's packages that mentions numba (path and text). Any edit of such a
module gives a new folder and a fresh compile of every kernel (once; the times
are in docs/results/minco.md#the-versioned-cache-across-checkouts-2026-11-29-thirtieth-and-thirty-first-sittings);
unchanged sources reuse it across runs and processes of one checkout. Not across checkouts at different paths: inside the
folder numba keys each entry by its source file's absolute folder (a SHA-1 of
the path), so a checkout elsewhere compiles its own entries. A new clone at the
same path reuses them: numba 0.68 stamps an entry with a SHA-256 of the source
file's contents (its mtime and size only key a memo). ``<base>`` is ``$NUMBA_CACHE_DIR`` if the user set it, else
``$XDG_CACHE_HOME/mpcde/numba`` (``~/.cache/mpcde/numba``), else, if that is
not writable, a folder in the temporary directory. Each package's
``__init__`` calls it before any of its modules is imported, so every kernel
is decorated after the folder is set; it does not import numba.
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

__all__ = ["PACKAGES", "kernel_digest", "use_versioned_cache"]

PACKAGES = ("sim", "perception", "planners", "mpcde")
"""The project's packages whose numba kernels share the versioned cache."""
_BASE_ENV = "MPCDE_NUMBA_CACHE_BASE"  # the base folder, handed to child processes (render and sweep workers)
_configured: dict[tuple[str, tuple[str, ...]], str] = {}


def kernel_digest(root: Path, packages: tuple[str, ...] = PACKAGES) -> str:
    """Hex SHA-256 of the modules under ``root/<package>/`` whose text mentions numba (relative path and bytes)."""
    h = hashlib.sha256()
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            data = path.read_bytes()
            if b"numba" in data:
                h.update(path.relative_to(root).as_posix().encode() + b"\0" + data + b"\0")
    return h.hexdigest()


def _default_base() -> str:
    xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    base = os.path.join(xdg, "mpcde", "numba")
    try:
        os.makedirs(base, exist_ok=True)
        if os.access(base, os.W_OK):
            return base
    except OSError:
        pass
    return os.path.join(tempfile.gettempdir(), f"mpcde-numba-{os.getuid() if hasattr(os, 'getuid') else 'user'}")


def use_versioned_cache(root: Path | None = None, packages: tuple[str, ...] = PACKAGES) -> str:
    """Point numba's cache at the folder of the current kernel sources; return that folder.

    Sets ``NUMBA_CACHE_DIR`` (read when numba is imported, here or in a child
    process) and, if numba is already imported, ``numba.config.CACHE_DIR``.
    ``root`` is the folder holding the packages (default: this checkout or
    installation). Idempotent per (root, packages).
    """
    root = Path(__file__).resolve().parent.parent if root is None else Path(root)
    key = (str(root), tuple(packages))
    if key in _configured:
        return _configured[key]
    base = os.environ.get(_BASE_ENV) or os.environ.get("NUMBA_CACHE_DIR") or _default_base()
    os.environ[_BASE_ENV] = base  # a child keeps the user's base, not this folder
    folder = os.path.join(base, "kernels-" + kernel_digest(root, packages)[:16])
    os.environ["NUMBA_CACHE_DIR"] = folder
    numba = sys.modules.get("numba")
    if numba is not None:
        numba.config.CACHE_DIR = folder
    _configured[key] = folder
    return folder
