"""`mpcde eval-mlr` from the command line: bad input is one line, exit 2, nothing written."""

import pytest

from mpcde.cli import main


def _exit_code(argv: list[str]) -> int:
    try:
        return main(argv)
    except SystemExit as e:  # argparse's own refusals (unknown choice)
        return int(e.code)


@pytest.mark.parametrize(
    "argv, prefix",
    [
        (["--seeds", "0"], "mpcde: error: --seeds=0: an integer >= 1"),
        (["--experiments", "fig5"], "mpcde: error: argument --experiments: invalid choice: 'fig5'"),
    ],
)
def test_bad_eval_mlr_input_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, argv, prefix):
    assert _exit_code(["eval-mlr", *argv, "--out", str(tmp_path / "mlr")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(prefix)
    assert list(tmp_path.iterdir()) == []
