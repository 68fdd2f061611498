"""emasim runs list / prune: only emasim's results, only their own files, a dry run by default."""

import errno
import json
import os
import time

from typer.testing import CliRunner

from emasim.cli import app
from emasim.output import write_folder, write_new
from emasim.results import choose, find, parse_age


def result_at(folder, age_s, kind="run"):
    """An emasim result written ``age_s`` seconds ago (its marker's time set back)."""
    write_folder(folder, lambda tmp: write_new(tmp / "metrics.json", "{}"), kind=kind)
    past = time.time() - age_s
    os.utime(folder / ".emasim-result", (past, past))
    return folder


def test_prune_removes_only_old_emasim_results_and_never_a_users_file(tmp_path):
    root = tmp_path / "runs"
    old = result_at(root / "speed-step" / "old", 10 * 86400)
    kept_by_user = result_at(root / "speed-step" / "annotated", 9 * 86400)
    (kept_by_user / "my-notes.txt").write_text("years of work")
    new = result_at(root / "speed-step" / "new", 60)
    study = result_at(root / "studies" / "s", 20 * 86400, kind="study")
    result_at(study / "runs" / "r1", 20 * 86400)
    mine = root / "mine"
    mine.mkdir()
    (mine / "data.csv").write_text("1,2\n")
    runner = CliRunner()
    dry = runner.invoke(app, ["runs", "prune", str(root), "--older-than", "7d"])
    assert dry.exit_code == 0, dry.output
    assert "would remove" in dry.output and old.exists() and study.exists()
    done = runner.invoke(app, ["runs", "prune", str(root), "--older-than", "7d", "--yes"])
    assert done.exit_code == 0, done.output
    assert not old.exists() and not study.exists() and new.exists()
    assert (kept_by_user / "my-notes.txt").read_text() == "years of work"
    assert "kept, it holds files emasim did not write (my-notes.txt)" in done.output
    assert (mine / "data.csv").read_text() == "1,2\n"
    listing = runner.invoke(app, ["runs", "list", str(root)])
    assert listing.exit_code == 0, listing.output
    assert "speed-step/new" in listing.output and "speed-step/annotated" in listing.output


def test_runs_list_names_each_result_whole_under_any_root_at_any_width(tmp_path, monkeypatch):
    """Each result relative to the root given, never cut mid-word: a root 200 characters deep
    and a 40-column console (the table is printed at the width its rows need); ``--json``
    gives the full paths. ``prune`` names them the same way, each on one line."""
    from emasim.cli import console

    root = tmp_path.joinpath(*["a-rather-long-folder-name"] * 8)
    names = ["speed-step/PI-against-SMC-2026-12-07", "studies/monte-carlo-of-the-bench"]
    for age, name in enumerate(names):
        result_at(root / name, 10 * 86400 - age)
    monkeypatch.setattr(console, "width", 40)
    runner = CliRunner()
    listing = runner.invoke(app, ["runs", "list", str(root)])
    assert listing.exit_code == 0, listing.output
    table = listing.stdout
    assert all(name in table for name in names) and str(tmp_path) not in table, table
    as_json = runner.invoke(app, ["runs", "list", str(root), "--json"])
    assert [row["folder"] for row in json.loads(as_json.stdout)] == [
        str((root / name).resolve()) for name in names
    ]
    dry = runner.invoke(app, ["runs", "prune", str(root), "--older-than", "1d"])
    assert all(f"would remove {name} (" in dry.stdout for name in names), dry.stdout


def test_keep_counts_the_newest_of_each_folder():
    class R:
        def __init__(self, parent, written):
            from pathlib import Path

            self.folder, self.written = Path(parent) / str(written), written

    results = [R("a", t) for t in (1, 2, 3)] + [R("b", 5)]
    assert [r.written for r in choose(results, None, keep=1, now=10)] == [1, 2]
    assert [r.written for r in choose(results, 7.5, keep=1, now=10)] == [1, 2]
    assert [r.written for r in choose(results, 8.5, keep=0, now=10)] == [1]


def test_bad_options_are_one_line(tmp_path):
    runner = CliRunner()
    for args, needle in (
        (["runs", "prune", str(tmp_path)], "give --older-than AGE, --keep N or both"),
        (["runs", "prune", str(tmp_path), "--older-than", "soon"], "e.g. 7d"),
        (["runs", "list", str(tmp_path / "none")], "no such folder"),
    ):
        out = runner.invoke(app, args)
        assert out.exit_code == 2 and needle in out.output, out.output
    assert parse_age("12h") == 43200 and find(tmp_path) == []


def test_prune_on_a_read_only_file_system_says_it_cannot_remove(tmp_path, monkeypatch):
    """Where emasim's own files cannot be removed (a read-only file system), prune says so in
    one line a result, keeps going, and never blames its own marker as a user's file."""
    root = tmp_path / "runs"
    old = result_at(root / "speed-step" / "old", 10 * 86400)
    unlink = os.unlink

    def read_only(path, *args, **kwargs):
        if str(path).startswith(str(root)):
            raise OSError(errno.EROFS, os.strerror(errno.EROFS), str(path))
        return unlink(path, *args, **kwargs)

    monkeypatch.setattr(os, "unlink", read_only)
    done = CliRunner().invoke(app, ["runs", "prune", str(root), "--older-than", "7d", "--yes"])
    assert done.exit_code == 0, done.output
    assert "cannot remove: read-only file system" in done.output
    assert "did not write" not in done.output and "removed speed-step" not in done.output
    assert (old / ".emasim-result").exists()
