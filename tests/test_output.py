"""Output safety: nothing emasim did not write is ever deleted, renamed or replaced.

The rules of emasim.output, each checked on real folders: a user's folder, file or link is
refused with or without force; an emasim result needs force; a write is atomic and leaves no
temporary behind on failure; leftovers of dead processes (and only those) are cleaned; two
writers to one place never both lose; modes follow the umask; JSON is valid JSON.
"""

import json
import os
import stat
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from emasim import output
from emasim.jsonio import json_text
from emasim.naming import fresh_folder
from emasim.output import (
    JOURNAL,
    MARKER,
    OutputError,
    check_target,
    clean_leftovers,
    foreign_files,
    is_emasim_folder,
    new_file,
    remove_own,
    write_file,
    write_folder,
    write_marker,
    write_new,
)


def fill(tmp):
    write_new(tmp / "a.txt", "new")


def dead_pid() -> int:
    """The pid of a process that has just exited (so surely not running)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def test_a_new_folder_is_written_with_the_marker_and_no_temporary(tmp_path):
    target = write_folder(tmp_path / "run", fill)
    assert is_emasim_folder(target) and (target / "a.txt").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("force", [False, True])
def test_a_users_folder_file_or_link_is_never_replaced(tmp_path, force):
    folder = tmp_path / "mydata"
    folder.mkdir()
    (folder / "thesis.tex").write_text("years of work")
    victim = tmp_path / "victim.txt"
    victim.write_text("mine")
    link = tmp_path / "link"
    link.symlink_to(folder)
    for target in (folder, victim, link, victim / "sub"):
        with pytest.raises(OutputError, match="emasim did not write|is a file"):
            write_folder(target, fill, force=force)
    assert (folder / "thesis.tex").read_text() == "years of work"
    assert victim.read_text() == "mine" and link.resolve() == folder.resolve()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "mydata", "victim.txt"]


def test_an_emasim_result_is_replaced_only_with_force(tmp_path):
    target = write_folder(tmp_path / "run", lambda tmp: write_new(tmp / "a.txt", "first"))
    with pytest.raises(OutputError, match="--force"):
        write_folder(target, fill)
    assert (target / "a.txt").read_text() == "first"
    write_folder(target, fill, force=True)
    assert (target / "a.txt").read_text() == "new" and is_emasim_folder(target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_an_empty_folder_is_taken(tmp_path):
    (tmp_path / "empty").mkdir()
    assert is_emasim_folder(write_folder(tmp_path / "empty", fill))


def test_a_failing_write_leaves_nothing(tmp_path):
    def broken(tmp):
        write_new(tmp / "half", "x")
        raise KeyboardInterrupt  # a Ctrl-C in the middle of the save

    with pytest.raises(KeyboardInterrupt):
        write_folder(tmp_path / "run", broken)
    assert list(tmp_path.iterdir()) == []


def test_leftovers_of_dead_processes_and_only_those_are_removed(tmp_path):
    pid = dead_pid()
    ours = tmp_path / f".run.tmp-{pid}-abcdef12"
    ours.mkdir()
    (ours / MARKER).write_text("{}")
    ours_old = tmp_path / f".run.old-{pid}-0123abcd"
    ours_old.mkdir()
    (ours_old / MARKER).write_text("{}")
    users = tmp_path / f".notes.tmp-{pid}-abcdef12"  # our pattern, but no marker: a user's
    users.mkdir()
    (users / "keep.txt").write_text("mine")
    alive = tmp_path / f".run.tmp-{os.getpid()}-abcdef12"  # a live process's: in use
    alive.mkdir()
    (alive / MARKER).write_text("{}")
    similar = tmp_path / ".run.tmp-xyz"  # not our pattern
    similar.mkdir()
    empty = tmp_path / f".run.tmp-{pid}-0000beef"  # killed before its marker: nothing inside
    empty.mkdir()
    bare = tmp_path / f".plant.fmu.tmp-{pid}-abcdef12.fmu"  # an earlier pattern, a bare file
    bare.write_text("a user's, for all emasim can tell")
    bare_now = tmp_path / f".plant.fmu.tmp-{pid}-abcdef12"  # our pattern, but a bare file
    bare_now.write_text("a user's, for all emasim can tell")
    no_process = tmp_path / f".run.tmp-{10**30}-abcdef12"  # no process can have that pid
    no_process.mkdir()
    (no_process / MARKER).write_text("{}")
    assert sorted(clean_leftovers(tmp_path)) == sorted([ours, ours_old, empty, no_process])
    assert (users / "keep.txt").read_text() == "mine" and alive.exists() and similar.exists()
    assert bare.read_text() == bare_now.read_text() == "a user's, for all emasim can tell"


def test_the_next_write_cleans_the_leftovers(tmp_path):
    pid = dead_pid()
    leftover = tmp_path / f".run.tmp-{pid}-abcdef12"
    leftover.mkdir()
    (leftover / MARKER).write_text("{}")
    write_folder(tmp_path / "other", fill)
    assert not leftover.exists()


def race(target: Path, writers: int, force: bool) -> list[str]:
    """``writers`` threads write ``target`` at once (each its number in who.txt, all held at a
    barrier inside the build): "ok" or the OutputError's message of each."""
    start = threading.Barrier(writers)
    outcomes = []

    def writer(n):
        def content(tmp):
            write_new(tmp / "who.txt", str(n))
            start.wait()

        try:
            write_folder(target, content, force=force)
            outcomes.append("ok")
        except OutputError as err:
            outcomes.append(str(err))

    threads = [threading.Thread(target=writer, args=(n,)) for n in range(writers)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return outcomes


def test_concurrent_writers_to_one_place_never_both_lose(tmp_path):
    """Eight threads race to one target without force: exactly one wins, the others are
    refused with an OutputError, and the folder is complete."""
    target = tmp_path / "run"
    outcomes = race(target, 8, force=False)
    assert outcomes.count("ok") == 1
    assert all("meanwhile" in o or "already" in o for o in outcomes if o != "ok")
    assert is_emasim_folder(target) and (target / "who.txt").read_text().isdigit()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_concurrent_forced_writers_to_one_place_all_succeed_in_turn(tmp_path):
    """With --force every writer replaces the result the one before it published (they take
    turns under the parent folder's lock); the last one stands, whole, with no debris."""
    target = write_folder(tmp_path / "run", fill)
    assert race(target, 4, force=True) == ["ok"] * 4
    assert foreign_files(target) == [] and (target / "who.txt").read_text().isdigit()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("force", [False, True])
def test_a_folder_put_at_the_target_while_building_is_never_replaced(tmp_path, force):
    target = tmp_path / "run"

    def content(tmp):
        fill(tmp)
        target.mkdir()  # a user's, made while emasim builds
        (target / "thesis.tex").write_text("years of work")

    with pytest.raises(OutputError, match="another process wrote it meanwhile"):
        write_folder(target, content, force=force)
    assert os.listdir(target) == ["thesis.tex"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


@pytest.mark.parametrize("system", ["renameat2", "rename"])
def test_the_publishing_rename_replaces_nothing_that_holds_anything(tmp_path, monkeypatch, system):
    """renameat2(RENAME_NOREPLACE) refuses every name that exists, an empty folder included
    (write_folder takes an empty folder by removing it first: rmdir removes nothing else).
    Where the system lacks it, rename(2) of a folder refuses all but an empty folder."""
    if system == "rename":
        monkeypatch.setattr(output, "_RENAMEAT2", None)
    elif output._RENAMEAT2 is None:
        pytest.skip("no renameat2 here")
    src = tmp_path / "new"
    src.mkdir()
    (src / "a.txt").write_text("new")
    users = tmp_path / "users"
    users.mkdir()
    (users / "thesis.tex").write_text("years of work")
    (tmp_path / "file.txt").write_text("mine")
    (tmp_path / "link").symlink_to(users)
    (tmp_path / "dangling").symlink_to("nowhere")
    for taken in ("users", "file.txt", "link", "dangling"):
        assert not output._rename(src, tmp_path / taken)
    (tmp_path / "empty").mkdir()
    assert output._rename(src, tmp_path / "empty") == (system == "rename")
    assert (users / "thesis.tex").read_text() == "years of work"
    assert (tmp_path / "file.txt").read_text() == "mine"
    assert os.readlink(tmp_path / "link") == str(users)
    assert os.readlink(tmp_path / "dangling") == "nowhere"
    target = write_folder(tmp_path / "run", fill)  # and a whole write, on either system
    assert is_emasim_folder(target)
    write_folder(target, fill, force=True)
    assert foreign_files(target) == [] and not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]


def test_concurrent_writers_to_fresh_names_all_succeed(tmp_path):
    start = threading.Barrier(4)
    written = []

    def writer():
        def content(tmp):
            start.wait()

        written.append(write_folder(fresh_folder(tmp_path, "run"), content, unique=True))

    threads = [threading.Thread(target=writer) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(set(written)) == 4 and all(is_emasim_folder(p) for p in written)


def test_modes_follow_the_umask(tmp_path):
    old = os.umask(0o027)
    try:
        target = write_folder(tmp_path / "run", fill)
        path = write_file(tmp_path / "f.txt", "x", is_ours=lambda _: True, what="--save")
    finally:
        os.umask(old)
    assert stat.S_IMODE(target.stat().st_mode) == 0o750
    assert stat.S_IMODE((target / "a.txt").stat().st_mode) == 0o640
    assert stat.S_IMODE(path.stat().st_mode) == 0o640


def test_files_follow_the_same_rules(tmp_path):
    ours = tmp_path / "tuned.toml"
    write_file(ours, "# emasim\n", is_ours=lambda p: p.read_text().startswith("# emasim"), what="x")
    with pytest.raises(OutputError, match="--force"):
        write_file(ours, "# emasim 2\n", is_ours=lambda p: True, what="x")
    write_file(ours, "# emasim 2\n", force=True, is_ours=lambda p: True, what="x")
    assert ours.read_text() == "# emasim 2\n"
    users = tmp_path / "notes.toml"
    users.write_text("mine")
    with pytest.raises(OutputError, match="did not write"):
        write_file(users, "x", force=True, is_ours=lambda p: False, what="x")
    assert users.read_text() == "mine"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["notes.toml", "tuned.toml"]


def test_a_file_a_function_or_blocks_are_written_as_given(tmp_path):
    """write_new copies a file given by its path byte for byte (a block at a time: this one
    spans three blocks of 1 MiB), hands a function the new file's handle, and writes
    blocks of text and bytes in turn."""
    source = tmp_path / "built.fmu"
    source.write_bytes(np.random.default_rng(3).bytes(2 * 2**20 + 123))
    write_new(tmp_path / "copy.fmu", source)
    write_new(tmp_path / "called.bin", lambda handle: handle.write(b"from a function"))
    write_new(tmp_path / "blocks.txt", ["a,", b"b", "\n"])
    assert (tmp_path / "copy.fmu").read_bytes() == source.read_bytes()
    assert (tmp_path / "called.bin").read_bytes() == b"from a function"
    assert (tmp_path / "blocks.txt").read_text() == "a,b\n"


def test_force_checks_a_file_again_just_before_replacing_it(tmp_path, monkeypatch):
    """A file that a user saved over emasim's while emasim worked (a tuning takes minutes) is
    the user's: --force checks it again under the lock, and refuses. Without --force a file
    that appears meanwhile is never replaced (the new file is hard-linked into place)."""
    ours = tmp_path / "tuned.toml"
    is_ours = lambda p: p.read_text().startswith("# emasim")  # noqa: E731
    write_file(ours, "# emasim\n", is_ours=is_ours, what="--save")
    real_locked = output.locked

    def user_saves_then_lock(folder):
        ours.write_text("mine")
        return real_locked(folder)

    monkeypatch.setattr(output, "locked", user_saves_then_lock)
    with pytest.raises(OutputError, match="emasim did not write it"):
        write_file(ours, "# emasim 2\n", force=True, is_ours=is_ours, what="--save")
    assert ours.read_text() == "mine"
    fresh = tmp_path / "fresh.toml"

    def appears_then_lock(folder):
        fresh.write_text("theirs")
        return real_locked(folder)

    monkeypatch.setattr(output, "locked", appears_then_lock)
    with pytest.raises(OutputError, match="meanwhile"):
        write_file(fresh, "# emasim\n", is_ours=is_ours, what="--save")
    assert fresh.read_text() == "theirs"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fresh.toml", "tuned.toml"]


def test_a_folder_that_cannot_be_written_is_one_error(tmp_path):
    with pytest.raises(OutputError, match="cannot write"):
        write_folder("/proc/emasim-cannot-write/run", fill)
    check_target(tmp_path / "new" / "deeper", force=False)  # creatable: fine


def test_json_is_valid_json():
    text = json_text({"a": float("nan"), "b": [float("inf"), 1.0], "c": {"d": -float("inf")}})

    def no_constants(name):
        raise ValueError(name)

    assert json.loads(text, parse_constant=no_constants) == {
        "a": None,
        "b": [None, 1.0],
        "c": {"d": None},
    }


def test_force_never_deletes_a_file_a_user_put_into_an_emasim_result(tmp_path):
    target = write_folder(tmp_path / "run", fill)
    (target / "my_notes.txt").write_text("observations")
    with pytest.raises(OutputError, match="emasim did not write, or changed since .my_notes.txt"):
        write_folder(target, fill, force=True)
    assert (target / "my_notes.txt").read_text() == "observations"
    (target / "my_notes.txt").unlink()
    write_folder(target, fill, force=True)  # only its own files again: replaceable


@pytest.mark.parametrize("edit", ["in place", "saved over", "same size, later"])
def test_force_never_deletes_a_file_a_user_changed_in_an_emasim_result(tmp_path, edit):
    """A file emasim wrote and a user then edited is the user's work: --force refuses to
    replace the result, and the edit stays. The manifest holds each file's size and
    modification time as published; an editor that saves a new file over the old one, or an
    edit of the same size, changes them too."""
    target = write_folder(tmp_path / "run", fill)
    mine = target / "a.txt"
    if edit == "in place":
        mine.write_text("my own conclusions")
    elif edit == "saved over":
        (target / "draft").write_text("my own conclusions")
        os.replace(target / "draft", mine)
    else:
        mine.write_text("NEW")
        os.utime(mine, ns=(mine.stat().st_atime_ns, mine.stat().st_mtime_ns + 10**9))
    with pytest.raises(OutputError, match="changed since .a.txt"):
        write_folder(target, fill, force=True)
    assert foreign_files(target) == ["a.txt"]
    assert not remove_own(target) and mine.exists()


def test_force_never_deletes_a_hard_link_a_user_made_in_an_emasim_result(tmp_path):
    """A hard link a user made in a published result to one of emasim's files is the user's
    name for that data: it is foreign, --force refuses, and both names stay."""
    target = write_folder(tmp_path / "run", fill)
    os.link(target / "a.txt", target / "kept.txt")
    with pytest.raises(OutputError, match="changed since .kept.txt"):
        write_folder(target, fill, force=True)
    assert (target / "kept.txt").read_text() == "new"


def test_a_result_moved_with_its_times_kept_is_still_emasims(tmp_path):
    """A result moved or copied with its files' times kept (mv, cp -a) may still be replaced:
    the manifest's stamps are size and modification time, not the inode."""
    target = write_folder(tmp_path / "run", fill)
    copy = tmp_path / "copy"
    subprocess.run(["cp", "-a", str(target), str(copy)], check=True)
    assert foreign_files(copy) == []
    write_folder(copy, fill, force=True)


def test_a_dead_runs_old_copy_holding_a_users_file_is_kept(tmp_path):
    target = write_folder(tmp_path / "run", fill)
    old = tmp_path / f".run.old-{dead_pid()}-abcdef12"
    target.rename(old)
    (old / "mine.txt").write_text("keep")
    assert clean_leftovers(tmp_path) == []
    assert (old / "mine.txt").read_text() == "keep"


def test_removal_deletes_only_the_manifests_files_never_through_a_link(tmp_path):
    """remove_own: a manifest naming a file outside the folder, or one reached through a
    link to a user's folder, deletes neither; a file not in the manifest stays too."""
    users = tmp_path / "users"
    users.mkdir()
    (users / "thesis.tex").write_text("years of work")
    (tmp_path / "outside.txt").write_text("mine")
    folder = write_folder(tmp_path / "run", fill)
    (folder / "via").symlink_to(users, target_is_directory=True)
    (folder / "mine.txt").write_text("keep")
    write_marker(folder, "run", files=["a.txt", "via/thesis.tex", "../outside.txt"])
    assert not remove_own(folder)
    assert (users / "thesis.tex").read_text() == "years of work"
    assert (tmp_path / "outside.txt").read_text() == "mine"
    assert (folder / "mine.txt").read_text() == "keep"
    assert not (folder / "a.txt").exists() and not (folder / MARKER).exists()


def test_a_name_the_manifest_lists_without_a_stamp_is_not_proof(tmp_path):
    """A manifest entry with no stamp (a manifest written before stamps) proves nothing: a
    user's file at that name is foreign, kept by remove_own and refused by --force."""
    folder = write_folder(tmp_path / "run", fill)
    (folder / "notes.txt").write_text("a user's")
    record = json.loads((folder / MARKER).read_text())
    record["files"].append("notes.txt")  # listed, no stamp
    (folder / MARKER).write_text(json.dumps(record))
    assert foreign_files(folder) == ["notes.txt"]
    with pytest.raises(OutputError, match="notes.txt"):
        write_folder(folder, fill, force=True)
    assert not remove_own(folder)
    assert (folder / "notes.txt").read_text() == "a user's"


def test_removal_through_a_link_to_a_result_removes_nothing(tmp_path):
    """remove_own given a link to an emasim result leaves the result whole."""
    folder = write_folder(tmp_path / "run", fill)
    link = tmp_path / "link"
    link.symlink_to(folder, target_is_directory=True)
    before = sorted(p.name for p in folder.iterdir())
    assert not remove_own(link)
    assert sorted(p.name for p in folder.iterdir()) == before and link.is_symlink()


def test_a_file_put_into_a_result_as_force_moves_it_aside_puts_it_back(tmp_path, monkeypatch):
    """--force moves the old result aside, then checks it against its manifest: a file that
    appears in it at that moment makes the check refuse, and the old result is put back in
    place with the file."""
    target = write_folder(tmp_path / "run", lambda tmp: write_new(tmp / "a.txt", "first"))
    real_rename = output._rename

    def rename_then_add(src, dst):
        moved = real_rename(src, dst)
        if ".old-" in Path(dst).name:
            (Path(dst) / "late.txt").write_text("keep")
        return moved

    monkeypatch.setattr(output, "_rename", rename_then_add)
    with pytest.raises(OutputError, match="late.txt"):
        write_folder(target, fill, force=True)
    assert (target / "late.txt").read_text() == "keep"
    assert (target / "a.txt").read_text() == "first" and foreign_files(target) == ["late.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run"]


def test_a_file_put_into_a_replaced_result_at_the_last_moment_is_kept(tmp_path, monkeypatch):
    """After the check, the new result is renamed into place and the old one, aside, loses its
    manifest's files only: a file that appears in it between the two stays, with its folder."""
    target = write_folder(tmp_path / "run", fill)
    real_rename = output._rename

    def rename_then_add(src, dst):
        moved = real_rename(src, dst)
        if ".tmp-" in Path(src).name:  # the new result is in place; the old one is aside
            [old] = [p for p in tmp_path.iterdir() if ".old-" in p.name]
            (old / "late.txt").write_text("keep")
        return moved

    monkeypatch.setattr(output, "_rename", rename_then_add)
    write_folder(target, fill, force=True)
    (kept,) = [p for p in tmp_path.iterdir() if ".old-" in p.name]
    assert sorted(p.name for p in kept.iterdir()) == ["late.txt"]
    assert (kept / "late.txt").read_text() == "keep"
    assert is_emasim_folder(target) and foreign_files(target) == []


def test_a_file_put_into_a_folder_being_built_survives_a_failed_write(tmp_path):
    """emasim's hidden build folder is open to anyone meanwhile: a file put there, even under
    a name emasim then tries to write, is not in the build journal, so the failed write
    removes emasim's own files only."""

    def broken(tmp):
        (tmp / "sub").mkdir()
        write_new(tmp / "sub" / "half", "x")
        (tmp / "mine.txt").write_text("keep")  # someone else's, put in meanwhile
        (tmp / "taken.txt").write_text("theirs")
        write_new(tmp / "taken.txt", "ours")  # refused: never opens an existing name

    with pytest.raises(OutputError, match="File exists"):  # one line, after the clean-up
        write_folder(tmp_path / "run", broken)
    [left] = tmp_path.iterdir()
    assert sorted(p.name for p in left.iterdir()) == ["mine.txt", "taken.txt"]
    assert (left / "taken.txt").read_text() == "theirs"


def test_a_killed_builds_leftover_loses_only_the_files_its_journal_lists(tmp_path):
    build = tmp_path / f".run.tmp-{dead_pid()}-abcdef12"
    build.mkdir()
    write_marker(build, "run")
    (build / "sub").mkdir()
    write_new(build / "a.txt", "ours")
    write_new(build / "sub" / "b.bin", b"ours")
    (build / "sub" / "notes.txt").write_text("someone's")
    assert foreign_files(build) == ["sub/notes.txt"]
    assert clean_leftovers(tmp_path) == []  # the foreign file keeps the folder
    assert [p.relative_to(build).as_posix() for p in sorted(build.rglob("*"))] == [
        "sub",
        "sub/notes.txt",
    ]
    (build / "sub" / "notes.txt").unlink()
    write_marker(build, "run")
    write_new(build / "c.txt", "ours")
    assert clean_leftovers(tmp_path) == [build] and not build.exists()


def test_a_file_put_in_while_building_is_published_as_foreign(tmp_path):
    """It is not in the manifest, so --force refuses to replace the result."""

    def content(tmp):
        fill(tmp)
        (tmp / "mine.txt").write_text("keep")

    target = write_folder(tmp_path / "run", content)
    assert foreign_files(target) == ["mine.txt"]
    assert not (target / JOURNAL).exists()
    with pytest.raises(OutputError, match="mine.txt"):
        write_folder(target, fill, force=True)
    assert (target / "mine.txt").read_text() == "keep"


def test_a_journalled_name_is_emasims_only_while_it_keeps_its_inode(tmp_path):
    """new_file journals each file's inode with its name: in a killed build, a file a user
    saved over one of emasim's (a new inode at that name) or linked to it (the inode under a
    name not journalled) is foreign and keeps the folder; the journalled files go."""
    build = tmp_path / f".run.tmp-{dead_pid()}-abcdef12"
    build.mkdir()
    write_marker(build, "run")
    for name in ("a.txt", "b.txt", "c.txt"):
        write_new(build / name, "ours")
    (build / "draft").write_text("my own conclusions")
    os.replace(build / "draft", build / "b.txt")  # an editor's save: a new file over it
    os.link(build / "c.txt", build / "kept.txt")
    assert foreign_files(build) == ["b.txt", "kept.txt"]
    assert clean_leftovers(tmp_path) == []
    assert sorted(p.name for p in build.iterdir()) == ["b.txt", "kept.txt"]
    assert (build / "b.txt").read_text() == "my own conclusions"


def test_a_build_killed_between_opening_and_journalling_keeps_its_folder(tmp_path):
    """Killed after new_file opened a name but before its journal line, a build holds a file
    nothing proves emasim's: it stays, and so does the folder (the safe way round)."""
    build = tmp_path / f".run.tmp-{dead_pid()}-abcdef12"
    build.mkdir()
    write_marker(build, "run")
    write_new(build / "metrics.json", "{}")
    (build / "result.parquet").write_bytes(b"")  # opened, never journalled
    assert foreign_files(build) == ["result.parquet"]
    assert clean_leftovers(tmp_path) == []
    assert sorted(p.name for p in build.iterdir()) == ["result.parquet"]


# A child process builds, and SIGKILLs itself inside new_file at the step named (argv): just
# before the journal line is written, or just before the unnamed file is linked to its name;
# "named" makes new_file take its way for a system without unnamed files.
KILLED_IN_NEW_FILE = """
import os, signal, sys
from pathlib import Path
from emasim import output
from emasim.manifest import write_marker
root, step, way = Path(sys.argv[1]), sys.argv[2], sys.argv[3]
build = root / f".run.tmp-{os.getpid()}-abcdef12"
build.mkdir()
write_marker(build, "run")
output.write_new(build / "metrics.json", "{}")
if way == "named":
    output._unnamed = lambda folder: None
def killed(*args):
    os.kill(os.getpid(), signal.SIGKILL)
setattr(output, {"journal": "_journal", "link": "_LINKAT"}[step], killed)
output.write_new(build / "result.parquet", b"x")
"""


@pytest.mark.parametrize(
    ("step", "way", "kept"),
    [("journal", "unnamed", []), ("link", "unnamed", []), ("journal", "named", ["result.parquet"])],
)
def test_a_build_killed_inside_new_file_leaves_only_what_it_listed(tmp_path, step, way, kept):
    """Made without a name, a file exists under its name only once it is listed: a build
    killed at any step of new_file loses everything at the next write there. Where a file is
    named first (no unnamed files on that system), a kill before its journal line leaves it
    unlisted, and it stays with its folder (the safe way round)."""
    if way == "unnamed":
        fd = output._unnamed(tmp_path)
        if fd is None:
            pytest.skip("this system makes no unnamed files (O_TMPFILE)")
        os.close(fd)
    child = subprocess.run([sys.executable, "-c", KILLED_IN_NEW_FILE, str(tmp_path), step, way])
    assert child.returncode == -9  # SIGKILL, at that step
    [build] = tmp_path.iterdir()
    assert clean_leftovers(tmp_path) == ([] if kept else [build])
    if kept:
        assert sorted(p.name for p in build.iterdir()) == kept
    else:
        assert not os.path.lexists(build)


def test_a_file_whose_journal_line_cannot_be_written_is_removed(tmp_path):
    """new_file journals a file after opening it: where the line cannot be written (a full
    disk; here the journal's name is taken by a folder), the file just made goes at once, so
    the failed write leaves nothing behind."""

    def content(tmp):
        (tmp / JOURNAL).mkdir()
        write_new(tmp / "a.txt", "x")

    with pytest.raises(OutputError, match="cannot write"):
        write_folder(tmp_path / "run", content)
    assert list(tmp_path.iterdir()) == []


def test_new_file_lists_what_it_wrote_and_leaves_nothing_else(tmp_path):
    def content(tmp):
        write_new(tmp / "a.txt", "x")
        with new_file(tmp / "b.bin") as handle:
            handle.write(b"y")

    target = write_folder(tmp_path / "run", content)
    assert sorted(p.name for p in target.iterdir()) == [MARKER, "a.txt", "b.bin"]
    assert json.loads((target / MARKER).read_text())["files"] == ["a.txt", "b.bin"]


def test_a_file_listed_into_a_result_rewrites_its_marker_whole_or_not_at_all(tmp_path, monkeypatch):
    """write_file(listed=True) adds the file to the result's manifest, every other entry kept;
    the marker is a new file renamed over the old one, so a failure (a kill) at the rename
    leaves the old marker whole, and the result still emasim's."""
    folder = write_folder(tmp_path / "r", fill)
    before = json.loads((folder / MARKER).read_text())
    write_file(folder / "t.bin", b"1", is_ours=lambda p: True, what="t", listed=True)
    after = json.loads((folder / MARKER).read_text())
    assert (
        after["files"] == ["a.txt", "t.bin"]
        and after["stamps"]["a.txt"] == before["stamps"]["a.txt"]
    )
    assert sorted(os.listdir(folder)) == sorted([MARKER, "a.txt", "t.bin"])

    def killed(*args):
        raise OSError("killed")

    monkeypatch.setattr(os, "replace", killed)
    with pytest.raises(OutputError, match="cannot write"):
        write_file(folder / "u.bin", b"2", is_ours=lambda p: True, what="t", listed=True)
    assert json.loads((folder / MARKER).read_text()) == after
    assert is_emasim_folder(folder) and "u.bin" in foreign_files(folder)


def test_a_journal_named_file_in_a_published_result_is_a_users(tmp_path):
    """Only a build keeps a journal: in a published result a file named like it is a user's.
    It proves nothing emasim's, is never removed, and keeps the result from being replaced."""
    folder = write_folder(tmp_path / "r", fill)
    (folder / "mine.txt").write_text("notes")
    st = os.lstat(folder / "mine.txt")
    (folder / JOURNAL).write_text(f"{st.st_dev}:{st.st_ino} mine.txt\n")
    assert foreign_files(folder) == [JOURNAL, "mine.txt"]
    assert not remove_own(folder)
    assert sorted(os.listdir(folder)) == [JOURNAL, "mine.txt"]
    assert (folder / "mine.txt").read_text() == "notes"
