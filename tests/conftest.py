"""Shared fixtures: fixed seeds, small scenes."""

from __future__ import annotations

import gzip
import shutil
from pathlib import Path
from typing import Callable

import mpcde  # noqa: F401  (its numerics profile is set before numpy loads: mpcde/numerics.py)
import numpy as np
import pytest

KEPT_STORES = Path(__file__).resolve().parents[1] / "docs" / "results" / "stores"
"""The sweep stores kept in the repository (docs/results/stores/README.md)."""


@pytest.fixture
def rng() -> np.random.Generator:
    """A generator with a fixed seed."""
    return np.random.default_rng(12345)


@pytest.fixture
def unpack_kept_store() -> Callable[[str, Path], Path]:
    """``unpack(name, folder)``: the kept store ``name`` as a sweep folder at ``folder`` (created): its sweep.json,
    and results.jsonl unpacked from results.jsonl.gz, as docs/results/stores/README.md says to. Returns ``folder``."""

    def unpack(name: str, folder: Path) -> Path:
        folder.mkdir(parents=True)
        shutil.copy(KEPT_STORES / name / "sweep.json", folder / "sweep.json")
        with gzip.open(KEPT_STORES / name / "results.jsonl.gz", "rb") as packed, open(folder / "results.jsonl", "wb") as out:
            shutil.copyfileobj(packed, out)
        return folder

    return unpack


ORCA_EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "orca_stack"
"""The worked third-party stack's source (its own pyproject.toml; docs/stacks.md)."""


@pytest.fixture(scope="session")
def orca_site(tmp_path_factory) -> Path:
    """A folder with examples/orca_stack installed into it, as ``pip install --target`` installs any package
    (no dependencies: mpcde is the running one). Put it on ``PYTHONPATH`` to have the stack in a process.

    The build runs in a copy of the source, so the checkout gets no build/ or egg-info folder.
    """
    import subprocess
    import sys

    root = tmp_path_factory.mktemp("orca")
    source, site = root / "source", root / "site"
    shutil.copytree(ORCA_EXAMPLE, source, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__"))
    cmd = [sys.executable, "-m", "pip", "install", "-q", "--no-deps", "--no-build-isolation", "--target", str(site), str(source)]
    subprocess.run(cmd, check=True, capture_output=True, timeout=300)
    return site
