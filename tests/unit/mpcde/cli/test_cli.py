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


def test_fly_denied_with_missing_detector_weights_is_one_line_exit_2_and_writes_nothing(tmp_path, capsys):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(
        "name: s\nduration_s: 1.0\ndrones:\n  layout: explicit\n  starts: [[-4.0, 0.0, 1.5]]\n  goals: [[4.0, 0.0, 1.5]]\n"
        f"planner:\n  kind: mpcde\nperception:\n  detector_weights: {tmp_path / 'none.pt'}\n"
    )
    out = tmp_path / "run"
    assert main(["fly", str(scenario), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mpcde: error: perception.detector_weights=") and err[0].endswith("missing")
    assert not out.exists() and [p.name for p in tmp_path.iterdir()] == ["s.yaml"]
