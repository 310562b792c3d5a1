"""Start a CLI subprocess that a test will interrupt with SIGINT, as a terminal's Ctrl-C would.

A process started in the background of a non-interactive shell (``cmd &``, or a
CI runner that does so) inherits SIGINT as ignored, and Python then installs
no KeyboardInterrupt handler: the child would fly on and the signal tests would
test nothing. The child here gets SIGINT's default disposition back before it
execs, so the tests mean the same wherever they are launched from.
"""

from __future__ import annotations

import signal
import subprocess
from typing import Any


def _sigint_default() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def start_interruptible(cmd: list[str], **kwargs: Any) -> subprocess.Popen:
    """``subprocess.Popen(cmd, stdout/stderr piped, text, new session, **kwargs)`` with SIGINT at its default."""
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
                            preexec_fn=_sigint_default, **kwargs)
