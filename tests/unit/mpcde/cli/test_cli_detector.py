"""`mpcde train-detector` and `mpcde eval-detector` from the command line."""

import json

import pytest

from mpcde.cli import main
from perception.detector.detector import DroneDetector


@pytest.mark.parametrize(
    "argv, field",
    [
        (["train-detector", "--frames", "3"], "--frames"),
        (["train-detector", "--epochs", "0"], "--epochs"),
        (["train-detector", "--minutes", "-1"], "--minutes"),
        (["train-detector", "--val-frames", "2"], "--val-frames"),
        (["eval-detector", "--frames", "0"], "--frames"),
        (["eval-detector", "--workers", "0"], "--workers"),
    ],
)
def test_bad_options_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, argv, field):
    out = tmp_path / "out"
    assert main([*argv, "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"mpcde: error: {field}=")
    assert not out.exists()


@pytest.mark.parametrize("content", [None, b"not a checkpoint", b""])
def test_missing_or_corrupt_weights_are_one_line_exit_2_and_write_nothing(tmp_path, capsys, content):
    weights = tmp_path / "w.pt"
    if content is not None:
        weights.write_bytes(content)
    out = tmp_path / "out"
    assert main(["eval-detector", "--out", str(out), "--weights", str(weights), "--frames", "6", "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "weights" in err[0] and str(weights) in err[0]
    assert not out.exists()


@pytest.mark.slow
def test_eval_detector_writes_the_issue_schema_on_a_few_held_out_frames(tmp_path, capsys):
    out = tmp_path / "ed"
    assert main(["eval-detector", "--out", str(out), "--frames", "12", "--workers", "1", "--quiet"]) == 0
    res = json.loads((out / "results.json").read_text())
    assert set(res) == {"overall", "by_distance", "latency_ms_per_frame"}
    assert set(res["overall"]) == {"precision", "recall", "ap50"}
    assert [(b["min_m"], b["max_m"]) for b in res["by_distance"]] == [(0, 2), (2, 4), (4, 6), (6, 8), (8, 10)]
    assert sum(b["n"] for b in res["by_distance"]) > 0
    assert all(set(b) == {"min_m", "max_m", "n", "precision", "recall", "ap50"} for b in res["by_distance"])
    assert res["latency_ms_per_frame"] > 0
    assert "recall" in capsys.readouterr().out


@pytest.mark.slow
def test_train_detector_from_nothing_writes_loadable_weights_and_a_model_card(tmp_path):
    out = tmp_path / "td"
    argv = ["train-detector", "--out", str(out), "--frames", "16", "--val-frames", "8", "--epochs", "1", "--quiet"]
    assert main(argv) == 0
    card = json.loads((out / "model_card.json").read_text())
    assert card["data"]["train_frames"] == 16 and card["data"]["val_frames"] == 8
    assert card["training"]["epochs_run"] == 1 and card["training"]["steps"] >= 1
    assert {"overall", "by_distance"} <= set(card["val_metrics"])
    detector = DroneDetector.load(out / "drone_detector.pt")
    assert 0.0 < detector.score_threshold < 1.0
    assert (out / "data" / "train" / "manifest.json").exists()
