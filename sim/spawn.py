"""Start ``spawn`` processes from any script, with or without an ``if __name__ == "__main__":`` guard.

A ``spawn`` child re-imports the parent's ``__main__`` module before it runs
its target, so a plain script that starts a render pool at import time would
start it again in every child, and multiprocessing stops with a bootstrapping
error that names nothing of ours. Every target this package starts (render
workers, compare flights, dataset renders) lives in an importable module, so
the child does not need the script at all: :func:`main_module_hidden` hides
``__main__``'s file and spec from :mod:`multiprocessing` while the processes
start, and the children skip it. The one thing this rules out, a target or
argument defined in the script itself, the package never does.
"""

from __future__ import annotations

import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["main_module_hidden", "sigint_ignored"]

_MISSING = object()


@contextmanager
def main_module_hidden() -> Iterator[None]:
    """Inside the block, spawned children do not re-import the parent's ``__main__`` script."""
    main = sys.modules.get("__main__")
    if main is None:
        yield
        return
    saved_file = main.__dict__.pop("__file__", _MISSING)
    saved_spec = main.__dict__.get("__spec__", _MISSING)
    main.__spec__ = None
    try:
        yield
    finally:
        if saved_file is not _MISSING:
            main.__file__ = saved_file
        if saved_spec is _MISSING:
            main.__dict__.pop("__spec__", None)
        else:
            main.__spec__ = saved_spec


@contextmanager
def sigint_ignored() -> Iterator[None]:
    """Processes started inside the block ignore SIGINT (the setting is inherited through exec, so even their start-up imports do).

    Ctrl-C reaches a terminal's whole process group. Worker pools (render
    workers, dataset renderers) are stopped by their parent, so a worker that
    took the signal itself would only print a traceback beside the parent's
    one-line message. Off the main thread (where signals cannot be set) this
    does nothing. A Ctrl-C in the parent while the block runs (starting the
    processes: milliseconds) is lost.
    """
    try:
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
