"""Command-line behaviour common to subcommands."""

from mpcde.cli import main


def test_eval_tracking_pipeline_with_missing_weights_is_refused_before_writing(tmp_path, capsys):
    out = tmp_path / "et"
    argv = ["eval-tracking", "--out", str(out), "--measurements", "pipeline", "--weights", str(tmp_path / "none.pt"), "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "weights" in err[0] and "missing" in err[0]
    assert not out.exists()


def test_unknown_subcommand_is_one_line_exit_2(capsys):
    try:
        main(["teleport"])
    except SystemExit as e:
        assert e.code == 2
    assert len(capsys.readouterr().err.strip().splitlines()) == 1
