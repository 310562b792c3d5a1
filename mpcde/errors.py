"""The package's exception types.

:class:`ConfigError` (an invalid setting or option: field path, value, what
is allowed; one line) is defined at the bottom layer, :mod:`sim.checks`, so
that every layer raises the same type; it is re-exported here.
:class:`MpcdeError` is the base of the integration layer's other errors. The
command line turns both into one line on stderr and exit status 2.
"""

from __future__ import annotations

from sim.checks import ConfigError

__all__ = ["ConfigError", "MpcdeError", "Terminated"]


class MpcdeError(Exception):
    """Base class of mpcde's errors that the command line turns into exit status 2."""


class Terminated(BaseException):
    """SIGTERM, raised in the main thread by the command line's handler so that staging folders are cleaned as on Ctrl-C.

    A ``BaseException`` like ``KeyboardInterrupt``: every ``except BaseException``
    cleanup (run folders, evaluations, pools) runs, and no ``except Exception`` swallows it.
    """
