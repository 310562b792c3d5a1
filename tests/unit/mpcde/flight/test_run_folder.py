"""All-or-nothing outputs of the evaluation commands (mpcde.flight.run_folder.staged_output)."""

import pytest

import mpcde.evals.dmpc as eval_dmpc
from mpcde.flight.run_folder import staged_output


def _no_staging_left(parent):
    return not [p for p in parent.iterdir() if ".partial-" in p.name]


def test_a_complete_block_creates_the_folder_with_every_file(tmp_path):
    out = tmp_path / "a" / "out"
    with staged_output(out) as stage:
        (stage / "results.json").write_text("{}")
        assert not out.exists()  # nothing visible before the block ends
        (stage / "results.txt").write_text("table")
    assert sorted(p.name for p in out.iterdir()) == ["results.json", "results.txt"]
    assert _no_staging_left(out.parent)


def test_a_failing_block_leaves_no_folder_and_no_staging(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(RuntimeError, match="flight failed"):
        with staged_output(out) as stage:
            (stage / "results.json").write_text("{}")
            raise RuntimeError("flight failed")
    assert not out.exists()
    assert _no_staging_left(tmp_path)


def test_a_failing_block_leaves_an_existing_folder_as_it_was(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.json").write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with staged_output(out) as stage:
            (stage / "results.json").write_text("new")
            raise KeyboardInterrupt
    assert (out / "results.json").read_text() == "old"
    assert _no_staging_left(tmp_path)


def test_into_a_non_empty_folder_same_names_are_replaced_and_others_kept(tmp_path):
    out = tmp_path / "out"
    (out / "plots").mkdir(parents=True)
    (out / "plots" / "old.png").write_text("x")
    (out / "results.json").write_text("old")
    (out / "notes.md").write_text("mine")
    with staged_output(out) as stage:
        (stage / "results.json").write_text("new")
        (stage / "plots").mkdir()
        (stage / "plots" / "new.png").write_text("y")
    assert (out / "results.json").read_text() == "new"
    assert (out / "notes.md").read_text() == "mine"
    assert [p.name for p in (out / "plots").iterdir()] == ["new.png"]
    assert _no_staging_left(tmp_path)


def test_eval_dmpc_that_fails_while_writing_leaves_nothing(tmp_path, monkeypatch):
    def broken_plot(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(eval_dmpc, "_plot", broken_plot)
    out = tmp_path / "eval"
    with pytest.raises(OSError, match="disk full"):
        eval_dmpc.run_eval_dmpc(out, methods=("on_demand",), scenarios=("antipodal",), progress=False, duration_s=0.2)
    assert not out.exists()
    assert _no_staging_left(tmp_path)
