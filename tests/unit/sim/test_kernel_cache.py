"""The versioned numba cache: an edited callee in another file is recompiled, where numba's own cache keeps it stale."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

from sim.kernel_cache import kernel_digest, use_versioned_cache

CALLER = """
from numba import njit
from pkgx.callee import term

@njit(cache=True)
def total(x):
    return term(x) + 1.0
"""
CALLEE = """
from numba import njit

@njit(cache=True)
def term(x):
    return {body}
"""


def _package(root: Path, versioned: bool) -> None:
    """A package whose cached ``total`` calls the cached ``term`` of another file (the callee: :func:`_callee`)."""
    pkg = root / "pkgx"
    pkg.mkdir()
    init = "from sim.kernel_cache import use_versioned_cache\nuse_versioned_cache(__import__('pathlib').Path(__file__).parent.parent, ('pkgx',))\n"
    (pkg / "__init__.py").write_text(init if versioned else "")
    (pkg / "caller.py").write_text(textwrap.dedent(CALLER))


def _callee(root: Path, body: str) -> None:
    (root / "pkgx" / "callee.py").write_text(textwrap.dedent(CALLEE.format(body=body)))


def _run(root: Path, cache_base: Path | None) -> float:
    """total(2.0) in a fresh process (numba compiles or loads from its cache)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(root), str(Path(__file__).resolve().parents[3])])}
    env.pop("MPCDE_NUMBA_CACHE_BASE", None)
    env["NUMBA_CACHE_DIR"] = ""  # numba's default: __pycache__ beside the source, unless the package versions it
    if cache_base is not None:
        env["MPCDE_NUMBA_CACHE_BASE"] = str(cache_base)
    out = subprocess.run([sys.executable, "-c", "from pkgx.caller import total; print(total(2.0))"], env=env, capture_output=True, text=True, check=True)
    return float(out.stdout)


def test_an_edited_callee_is_recompiled_with_the_versioned_cache_and_stale_without(tmp_path):
    results = {}
    for versioned in (False, True):
        root = tmp_path / ("versioned" if versioned else "plain")
        root.mkdir()
        _package(root, versioned)
        _callee(root, "x * 10.0")
        first = _run(root, tmp_path / "cache" if versioned else None)
        _callee(root, "x * 100.0")  # the callee gains a factor of ten; the caller's file is untouched
        results[versioned] = (first, _run(root, tmp_path / "cache" if versioned else None))
    assert results[False] == (21.0, 21.0)  # numba's own cache: the caller kept the old callee (the trap)
    assert results[True] == (21.0, 201.0)  # versioned: recompiled


def test_the_digest_follows_kernel_sources_only_and_the_folder_is_handed_to_numba(tmp_path, monkeypatch):
    (tmp_path / "pkgy").mkdir()
    (tmp_path / "pkgy" / "k.py").write_text("import numba\n")
    (tmp_path / "pkgy" / "plain.py").write_text("x = 1\n")
    d0 = kernel_digest(tmp_path, ("pkgy",))
    (tmp_path / "pkgy" / "plain.py").write_text("x = 2\n")  # no numba: not part of the digest
    assert kernel_digest(tmp_path, ("pkgy",)) == d0
    (tmp_path / "pkgy" / "k.py").write_text("import numba  # edited\n")
    d1 = kernel_digest(tmp_path, ("pkgy",))
    assert d1 != d0
    import numba

    monkeypatch.setenv("MPCDE_NUMBA_CACHE_BASE", str(tmp_path / "base"))
    monkeypatch.setenv("NUMBA_CACHE_DIR", os.environ.get("NUMBA_CACHE_DIR", ""))  # both restored after the test
    monkeypatch.setattr(numba.config, "CACHE_DIR", numba.config.CACHE_DIR)
    folder = use_versioned_cache(tmp_path, ("pkgy",))
    assert folder == str(tmp_path / "base" / f"kernels-{d1[:16]}") == os.environ["NUMBA_CACHE_DIR"]
    assert numba.config.CACHE_DIR == folder
