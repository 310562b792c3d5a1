"""`mpcde compare` from the command line: bad input is one line, exit 2, nothing written."""

import pytest

from mpcde.cli import main


@pytest.mark.parametrize(
    "argv, field",
    [
        (["crossing", "--modes", "teleport"], "--modes"),
        (["crossing", "--modes", "comm", "comm"], "--modes"),
        (["crossing", "--seeds", "0"], "--seeds"),
        (["crossing", "--duration", "0"], "--duration"),
        (["crossing", "--duration", "-3"], "--duration"),
        (["no_such_scenario"], "scenario"),
        (["crossing", "--jobs", "0"], "--jobs"),
    ],
)
def test_bad_compare_input_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys, argv, field):
    out = tmp_path / "cmp"
    assert main(["compare", *argv, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"mpcde: error: {field}=")
    assert not out.exists() and list(tmp_path.iterdir()) == []


def test_an_out_that_is_a_file_is_refused(tmp_path, capsys):
    out = tmp_path / "a_file"
    out.write_text("x")
    assert main(["compare", "crossing", "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mpcde: error: --out=") and "not a folder" in err[0]
    assert out.read_text() == "x" and [p.name for p in tmp_path.iterdir()] == ["a_file"]
