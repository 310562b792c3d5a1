"""A signal that surfaces wrapped (numba's dispatcher turns an exception raised by a signal handler during a compiled
call into a SystemError whose context is that exception) still ends in the one line and its exit status."""

from __future__ import annotations

import signal

import pytest

import mpcde.cli as cli
from mpcde.errors import Terminated


@pytest.fixture(autouse=True)
def _restore_signals():
    """main() ignores SIGINT and SIGTERM after an interrupted command; keep this process's handlers as they were."""
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    for s, handler in saved.items():
        signal.signal(s, handler)


@pytest.mark.parametrize("signal_exc, code, line", [
    (Terminated(), 143, "mpcde: terminated, nothing written"),
    (KeyboardInterrupt(), 130, "mpcde: interrupted, nothing written"),
])  # fmt: skip
def test_a_signal_wrapped_in_system_error_is_one_line(monkeypatch, capsys, signal_exc, code, line):
    def wrapped(args):
        try:
            raise signal_exc
        except BaseException:
            raise SystemError("CPUDispatcher(<function _astar>) returned a result with an exception set")

    monkeypatch.setitem(cli._COMMANDS, "report", wrapped)
    assert cli.main(["report", "nowhere"]) == code
    assert capsys.readouterr().err.strip().splitlines() == [line]


def test_a_system_error_without_a_signal_is_not_hidden(monkeypatch):
    def broken(args):
        raise SystemError("a real bug")

    monkeypatch.setitem(cli._COMMANDS, "report", broken)
    with pytest.raises(SystemError, match="a real bug"):
        cli.main(["report", "nowhere"])
