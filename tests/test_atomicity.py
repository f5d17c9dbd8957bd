"""Hostile round ten: a command that fails leaves its folder as it was.

``atomic.removed_on_error`` puts an existing folder back (files replaced, deleted or
changed in place, folders removed) and removes what a failed command made, parents of its
``--out`` included; ``report --run`` failing after it wrote its files leaves the run
verifying; an export that changes the scenario files removes the report describing the
previous ones; ``run`` refuses a clash with the run folder's search before any stage
writes, and a job that fails over an earlier run leaves it as it was. (The one-line cases
are in the bad-input corpus, ``# round 10``.)"""

from __future__ import annotations

import fcntl
import os
import shutil
import struct
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import Any

import pytest

import sensorgap
from sensorgap.atomic import RESTORE_PREFIX, atomic_write_text, removed_on_error
from sensorgap.cli import main
from sensorgap.config.presets import templates_dir
from sensorgap.errors import InputError
from sensorgap.filesio import read_manifest, verify_manifest, write_manifest
from sensorgap.locks import folder_lock
from tests.bad_inputs.harness import tree_state
from tests.forked import run_forked

SRC = str(Path(sensorgap.__file__).resolve().parents[1])


# -- removed_on_error ------------------------------------------------------------------


def _folder(root: Path) -> Path:
    (root / "sub").mkdir(parents=True)
    (root / "a.txt").write_text("a")
    (root / "sub" / "b.txt").write_text("b")
    (root / "gone").mkdir()
    (root / "gone" / "c.txt").write_text("c")
    (root / "empty").mkdir()
    (root / "store.sqlite").write_bytes(b"stored")
    return root


@pytest.mark.parametrize("stop", [OSError, KeyboardInterrupt])
def test_a_failed_block_puts_an_existing_folder_back(
    tmp_path: Path, stop: type[BaseException]
) -> None:
    """Files replaced (renamed onto), deleted or changed in place, folders removed and
    made, a manifest written: after an error or an interrupt the folder is exactly as it
    was, and the restore folder is gone (never listed by the manifest written inside)."""
    root = _folder(tmp_path / "run")
    before = tree_state(root)
    with pytest.raises(stop), removed_on_error(root, copies=("store.sqlite",)):
        atomic_write_text(root / "a.txt", "new a")
        (root / "sub" / "b.txt").unlink()
        shutil.rmtree(root / "gone")
        (root / "empty").rmdir()
        atomic_write_text(root / "new" / "deeper" / "d.txt", "d")
        with open(root / "store.sqlite", "r+b") as fh:  # as SQLite does: in place
            fh.write(b"STORED")
        assert [p.name for p in root.iterdir() if p.name.startswith(RESTORE_PREFIX)]
        write_manifest(root)
        assert not [rel for rel in read_manifest(root) if RESTORE_PREFIX in rel]
        raise stop()
    assert tree_state(root) == before


def test_a_successful_block_keeps_its_changes_and_no_restore_folder(tmp_path: Path) -> None:
    root = _folder(tmp_path / "run")
    with removed_on_error(root, copies=("store.sqlite",)):
        atomic_write_text(root / "a.txt", "new a")
        (root / "sub" / "b.txt").unlink()
    assert (root / "a.txt").read_text() == "new a" and not (root / "sub" / "b.txt").exists()
    assert not [p for p in root.iterdir() if p.name.startswith(RESTORE_PREFIX)]


def test_a_failed_block_removes_only_the_folders_it_made(tmp_path: Path) -> None:
    """--out a/b/c/out whose b, c and out did not exist: b, c and out removed again; a
    and what it held stay."""
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "keep.txt").write_text("mine")
    out = tmp_path / "a" / "b" / "c" / "out"
    with pytest.raises(OSError), removed_on_error(out):
        atomic_write_text(out / "x.txt", "x")
        raise OSError(28, "No space left on device")
    assert sorted(p.name for p in (tmp_path / "a").iterdir()) == ["keep.txt"]


def test_only_the_named_files_are_kept_and_removed(tmp_path: Path) -> None:
    """``only`` (evaluate, probe into a user's folder): the other files there are neither
    linked nor touched; a new file of the block removed, a replaced one put back."""
    (tmp_path / "mine.txt").write_text("mine")
    (tmp_path / "trace.csv").write_text("old trace")
    before = tree_state(tmp_path)
    with (
        pytest.raises(OSError),
        removed_on_error(tmp_path, only=("evaluation.json", "trace.csv")),
    ):
        atomic_write_text(tmp_path / "trace.csv", "new trace")
        atomic_write_text(tmp_path / "evaluation.json", "{}")
        assert [p for p in tmp_path.iterdir() if p.name.startswith(RESTORE_PREFIX)]
        assert os.stat(tmp_path / "mine.txt").st_nlink == 1  # not linked: not kept
        raise OSError(28, "No space left on device")
    assert tree_state(tmp_path) == before


def test_a_killed_commands_restore_folder_is_reported_then_removed(tmp_path: Path) -> None:
    """A restore folder left by a command killed with SIGKILL: verify names it (one
    line); the next manifest written by a process holding the folder's
    lock removes it (not one in use); one written without the lock leaves it (it may be
    another running command's)."""
    root = tmp_path / "run"
    root.mkdir()
    (root / "a.txt").write_text("a")
    write_manifest(root)
    left = root / f"{RESTORE_PREFIX}abcd1234.tmp"
    left.mkdir()
    os.link(root / "a.txt", left / "0")
    problems = verify_manifest(root)
    assert len(problems) == 1 and "left over from a killed command" in problems[0], problems
    write_manifest(root)
    assert left.exists()
    with folder_lock(root):
        write_manifest(root)
    assert not left.exists() and verify_manifest(root) == []


def test_verify_of_a_folder_another_command_writes_calls_nothing_left_over(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round thirteen: ``verify`` while a command wrote the folder (its lock held,
    its restore folder there) called that restore folder "left over from a killed
    command" and advised deleting it. Now: the folder's lock held elsewhere -> one line
    saying a command is writing it, exit 2; a sub-folder's restore folder in use (that
    sub-folder's lock held) is named as such; released, a left-over is reported again."""
    root = tmp_path / "run"
    (root / "sub").mkdir(parents=True)
    (root / "a.txt").write_text("a")
    (root / "sub" / "b.txt").write_text("b")
    write_manifest(root)
    for where in (root, root / "sub"):
        (where / f"{RESTORE_PREFIX}abcd1234.tmp").mkdir()
        os.link(
            where / ("a.txt" if where == root else "b.txt"),
            where / f"{RESTORE_PREFIX}abcd1234.tmp" / "0",
        )
    capsys.readouterr()
    with held_elsewhere(root):
        assert main(["verify", str(root)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "being written by another sensorgap command now" in err[0], err
    assert "left over" not in err[0] and "delete" not in err[0], err
    new = tmp_path / "new"  # a run being made: no manifest yet (it said "not a sensorgap
    new.mkdir()  # run"; hostile round 41, a remark)
    with held_elsewhere(new):
        assert main(["verify", str(new)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "being written by another sensorgap command now" in err[0], err
    with held_elsewhere(root / "sub"):
        problems = verify_manifest(root)
    in_use = [p for p in problems if p.startswith(f"sub/{RESTORE_PREFIX}")]
    assert len(in_use) == 1 and "writing sub now (its lock is held)" in in_use[0], problems
    assert "left over" not in in_use[0]
    problems = verify_manifest(root)
    assert len(problems) == 2 and all("left over from a killed" in p for p in problems)


def test_a_sigkilled_commands_restore_folder_can_be_put_back_by_hand(tmp_path: Path) -> None:
    """Hostile round eleven (F11): a command killed with SIGKILL half-way left its restore
    folder holding numbered copies and nothing saying which file each was. Now its
    index.json names each number's path, verify says so in one line (not one line per
    copy), and moving the copies back by that index gives a folder that verifies."""
    import json
    import signal

    root = tmp_path / "run"
    (root / "sub").mkdir(parents=True)
    (root / "a.txt").write_text("a")
    (root / "sub" / "b.txt").write_text("b")
    write_manifest(root)
    child = (
        "import os, signal, sys\n"
        "from pathlib import Path\n"
        "from sensorgap.atomic import removed_on_error, atomic_write_text\n"
        "root = Path(sys.argv[1])\n"
        "with removed_on_error(root):\n"
        "    atomic_write_text(root / 'a.txt', 'half')\n"
        "    (root / 'sub' / 'b.txt').unlink()\n"
        "    os.kill(os.getpid(), signal.SIGKILL)\n"
    )
    done = subprocess.run([sys.executable, "-c", child, str(root)], check=False)
    assert done.returncode == -signal.SIGKILL
    (left,) = [p for p in root.iterdir() if p.name.startswith(RESTORE_PREFIX)]
    index = json.loads((left / "index.json").read_text(encoding="ascii"))
    assert sorted(index.values()) == ["a.txt", "manifest.json", "sub/b.txt"]
    problems = verify_manifest(root)
    mine = [p for p in problems if p.startswith(left.name)]
    assert len(mine) == 1 and "the 3 files" in mine[0] and "index.json" in mine[0], problems
    assert any("a.txt was changed" in p for p in problems)
    for number, rel in index.items():  # what the line tells the user to do (mv)
        if (root / rel).exists() and os.path.samefile(left / number, root / rel):
            (left / number).unlink()  # unchanged: the copy is a second link to it
        else:
            os.replace(left / number, root / rel)
    (left / "index.json").unlink()
    left.rmdir()
    assert verify_manifest(root) == []
    assert (root / "a.txt").read_text() == "a"


def test_a_folder_moved_while_its_command_runs_is_not_made_again(tmp_path: Path) -> None:
    """Hostile round eleven (F4): a run folder moved away (or deleted) while a command
    ran; the command failed, and its restore made a skeleton of empty folders at the old
    path. Now nothing is made or removed at a path whose folder is no longer the one the
    command started in: the moved folder keeps what it holds and its restore folder,
    which verify reports with its index."""
    root = tmp_path / "run"
    (root / "sub").mkdir(parents=True)
    (root / "sub" / "b.txt").write_text("b")
    moved = tmp_path / "moved"
    with pytest.raises(OSError, match="No space"), removed_on_error(root):
        atomic_write_text(root / "new.txt", "half")
        os.rename(root, moved)
        raise OSError(28, "No space left on device")
    assert not root.exists()
    assert (moved / "new.txt").read_text() == "half" and (moved / "sub" / "b.txt").is_file()
    (left,) = [p for p in moved.iterdir() if p.name.startswith(RESTORE_PREFIX)]
    assert (left / "index.json").is_file()
    deleted = tmp_path / "gone"
    deleted.mkdir()
    (deleted / "a.txt").write_text("a")
    with pytest.raises(OSError, match="No space"), removed_on_error(deleted):
        shutil.rmtree(deleted)
        raise OSError(28, "No space left on device")
    assert not deleted.exists()


@contextmanager
def held_elsewhere(folder: Path) -> Iterator[None]:
    """``folder``'s lock held as another process holds it (an ``flock`` on a second
    open file description conflicts with this process's own ``locks.folder_lock``)."""
    fd = os.open(folder, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)


# -- report and export of a finished run -----------------------------------------------


@pytest.fixture(scope="module")
def reported_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small search of System B, exported and reported (OpenSCENARIO 1.2, maneuver)."""
    run = tmp_path_factory.mktemp("reported") / "run"
    argv = ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve"]
    argv += ["--environments", "snow", "--budget", "30", "--top", "2", "--out", str(run)]
    assert main(argv) == 0
    assert main(["export", "--run", str(run)]) == 0
    assert main(["report", "--run", str(run)]) == 0
    assert main(["verify", str(run)]) == 0
    return run


@pytest.mark.parametrize("fails", ["manifest", "report.md"])
def test_a_report_failing_after_its_files_were_written_leaves_the_run_verifying(
    reported_run: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    fails: str,
) -> None:
    """Hostile round ten: ``report --run`` with a run file it cannot read (chmod 000
    scenarios/ as a user) failed while hashing the folder for its manifest, after
    report.html and report.md had been replaced: verify failed. Likewise a write failing
    between report.html and report.md. Now the earlier report is back in place."""
    import sensorgap.report.build as build
    import sensorgap.steps as steps

    run = tmp_path / "run"
    shutil.copytree(reported_run, run)
    before = tree_state(run)
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "0")  # the new report differs from the old
    if fails == "manifest":

        def unreadable(folder: str | Path, *_: object) -> Path:
            raise PermissionError(13, "Permission denied", str(Path(folder) / "scenarios"))

        monkeypatch.setattr(steps, "write_manifest", unreadable)
    else:
        write = build.atomic_write_text

        def full(path: str | Path, text: str) -> Path:
            if Path(path).name == fails:
                raise OSError(28, "No space left on device", str(path))
            return write(path, text)

        monkeypatch.setattr(build, "atomic_write_text", full)
    capsys.readouterr()
    assert main(["report", "--run", str(run)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot write or read" in err[0], err
    monkeypatch.undo()
    assert tree_state(run) == before
    assert main(["verify", str(run)]) == 0


def test_a_failed_restore_copy_names_the_file_being_kept(
    reported_run: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Hostile round 11 (F10): the restore copy of a file (search.sqlite, or every file
    where hard links fail) running out of room named the hidden copy,
    ``run/.sensorgap-restore.rp2za8ih.tmp/37``. Now the line names the file being kept,
    and the folder is as it was."""
    import errno

    import sensorgap.atomic as atomic

    run = tmp_path / "run"
    shutil.copytree(reported_run, run)
    before = tree_state(run)

    def no_link(*_: object) -> None:
        raise OSError(errno.EXDEV, "Invalid cross-device link")

    def full(src: str | Path, dst: str | Path) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(src), str(dst))

    monkeypatch.setattr(atomic.os, "link", no_link)
    monkeypatch.setattr(atomic.shutil, "copy2", full)
    capsys.readouterr()
    assert main(["report", "--run", str(run)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    monkeypatch.undo()
    assert len(err) == 1 and RESTORE_PREFIX not in err[0], err
    named = err[0].removeprefix("sensorgap: error: ").split(": cannot write or read: ")[0]
    assert named.startswith(str(run) + "/") and (Path(named)).is_file(), err
    assert "No space left on device (keeping a copy to restore on failure)" in err[0]
    assert tree_state(run) == before


def test_an_export_that_changes_the_scenario_files_removes_the_stale_report(
    reported_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round ten: ``export --osc-version 1.0 --style replay`` over an exported and
    reported run kept report.html/report.md ("OpenSCENARIO 1.2"), certified. An export
    that changes any scenario file's bytes (or catalog.json) now removes the report, as
    one changing the set of files did; an export giving the same files keeps it."""
    run = tmp_path / "run"
    shutil.copytree(reported_run, run)
    assert "OpenSCENARIO 1.2" in (run / "report.md").read_text(encoding="utf-8")
    capsys.readouterr()
    argv = ["export", "--run", str(run), "--osc-version", "1.0", "--style", "replay"]
    assert main(argv) == 0
    assert "the export changed the scenario files: removed" in capsys.readouterr().out
    for name in ("report.html", "report.md", "report"):
        assert not (run / name).exists(), name
    assert main(["verify", str(run)]) == 0
    assert main(["report", "--run", str(run)]) == 0
    assert "OpenSCENARIO 1.0" in (run / "report.md").read_text(encoding="utf-8")
    capsys.readouterr()
    assert main(argv) == 0  # the same files again: the report stays
    assert "removed" not in capsys.readouterr().out
    assert (run / "report.html").is_file() and main(["verify", str(run)]) == 0


# -- the main job over an earlier run --------------------------------------------------

JOB = ["--budget", "60", "--seeds", "1", "--families", "slow_ahead_curve", "--workers", "1"]


def _job_argv(vehicle: Path | str, out: Path, *more: str, env: str = "clear") -> list[str]:
    return ["run", "--vehicle", str(vehicle), "--out", str(out), *JOB, "--environments", env, *more]


@pytest.fixture(scope="module")
def job(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(a finished small job's --out, the vehicle file it ran: System B's preset copied
    to ``system_b.toml``)."""
    base = tmp_path_factory.mktemp("job")
    vehicle = base / "vehicle" / "system_b.toml"
    vehicle.parent.mkdir()
    shutil.copyfile(templates_dir() / "vehicles" / "system_b.toml", vehicle)
    out = base / "out"
    assert main(_job_argv(vehicle, out)) == 0
    assert main(["verify", str(out / "system_b")]) == 0
    return out, vehicle


def _rear_only(path: Path) -> Path:
    """A vehicle file named like System B's with only rear-facing sensors kept."""
    import re

    text = (templates_dir() / "vehicles" / "system_b.toml").read_text(encoding="utf-8")
    blocks = re.split(r"(?m)^(?=\[\[sensors\]\])", text)
    rear = [b for b in blocks[1:] if re.search(r"(?m)^yaw_deg = (1[0-9]{2}|-1[0-9]{2})", b)]
    assert rear, "System B has rear-facing sensors"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(blocks[0] + "".join(rear), encoding="utf-8")
    return path


@pytest.mark.slow
@pytest.mark.parametrize(
    "clash", ["environments", "same_name_other_file", "vehicle_edited", "search_running"]
)
def test_run_refuses_a_clash_with_the_earlier_search_before_any_work(
    job: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], clash: str
) -> None:
    """Hostile round ten: ``run`` into an earlier run with other environments (or
    another vehicle file of the same stem, or the same vehicle file edited) wrote the
    coverage, near and far field into the certified run before its search refused the
    store: verify failed and the original command was refused too. Now refused before
    any stage writes: one line, exit 2, the folder byte for byte as it was. So is a job
    into a folder a search is writing now (its lock held)."""
    src, vehicle = job
    out = tmp_path / "out"
    shutil.copytree(src, out)
    before = tree_state(out)
    text = vehicle.read_text(encoding="utf-8")
    try:
        if clash == "environments":
            argv, why = _job_argv(vehicle, out, env="fog_50"), "holds a search with different"
        elif clash == "same_name_other_file":
            other = _rear_only(tmp_path / "alt" / "system_b.toml")
            argv, why = _job_argv(other, out), "holds a search with different settings"
        elif clash == "vehicle_edited":
            vehicle.write_text(text + "\n# edited\n", encoding="utf-8")
            argv, why = _job_argv(vehicle, out), "holds results for other input files"
        else:
            argv, why = _job_argv(vehicle, out), "another sensorgap command is writing this folder"
        capsys.readouterr()
        with held_elsewhere(out / "system_b") if clash == "search_running" else nullcontext():
            assert main(argv) == 2
    finally:
        vehicle.write_text(text, encoding="utf-8")
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and why in err[0] and "system_b" in err[0], err
    assert tree_state(out) == before
    assert main(["verify", str(out)]) == 0 and main(["verify", str(out / "system_b")]) == 0


@pytest.mark.slow
def test_run_again_with_a_larger_budget_continues_the_earlier_run(
    job: tuple[Path, Path], tmp_path: Path
) -> None:
    """The same job with a larger budget resumes the earlier search and certifies the
    folder again (it was refused at its export: the job's own new ranking counted as
    "changed by hand" against the earlier manifest)."""
    src, vehicle = job
    out = tmp_path / "out"
    shutil.copytree(src, out)
    argv = _job_argv(vehicle, out)
    argv[argv.index("60")] = "90"
    assert main(argv) == 0
    assert main(["verify", str(out)]) == 0 and main(["verify", str(out / "system_b")]) == 0
    assert not [p for p in out.iterdir() if p.name.startswith(RESTORE_PREFIX)]


@pytest.mark.slow
def test_a_job_failing_over_an_earlier_run_leaves_it_as_it_was(
    job: tuple[Path, Path], tmp_path: Path
) -> None:
    """A full disk (RLIMIT_FSIZE) during a job with a larger budget over an earlier run:
    its search stored more candidates (in place) and rewrote the ranking and run.json
    before the coverage stage beside it failed. Now everything is put back, the search
    store included, and both folders verify."""
    import resource

    src, vehicle = job
    out = tmp_path / "out"
    shutil.copytree(src, out)
    before = tree_state(out)
    argv = _job_argv(vehicle, out)
    argv[argv.index("60")] = "90"
    argv[argv.index("--workers") + 1] = "2"  # the coverage in a second process fails

    def cap() -> None:
        resource.setrlimit(resource.RLIMIT_FSIZE, (700_000, 700_000))

    code, stderr = run_forked(argv, cap)  # a process of its own: the limit holds there only
    err = stderr.strip().splitlines()
    assert code == 2 and len(err) == 1 and "File too large" in err[0], err
    assert tree_state(out) == before
    assert main(["verify", str(out)]) == 0 and main(["verify", str(out / "system_b")]) == 0


@pytest.mark.parametrize("entry", ["keep.tmp/x", f"{RESTORE_PREFIX}abcdefgh.tmp/data.txt"])
def test_an_out_holding_a_users_temporary_looking_folder_is_refused_and_kept(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], entry: str
) -> None:
    """Hostile round 11 (F6): ``nearfield --out ud`` with a user's ``ud/keep.tmp/x``
    exited 0 and its manifest failed verify ("a left-over temporary"); a user's
    ``ud/.sensorgap-restore.abcdefgh.tmp/data.txt`` was silently deleted by
    write_manifest. Both are refused up front and kept; write_manifest itself refuses
    and deletes only a restore folder holding numbered files."""
    out = tmp_path / "ud"
    (out / entry).parent.mkdir(parents=True)
    (out / entry).write_text("mine")
    before = tree_state(out)
    capsys.readouterr()
    argv = ["nearfield", "--vehicle", "system_a", "--resolution", "1", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"holds {entry}, named like a left-over temporary" in err[0], err
    assert tree_state(out) == before
    with pytest.raises(InputError, match="manifest.json: not written: the folder holds"):
        write_manifest(out)
    assert tree_state(out) == before


def test_a_fifo_in_a_folder_is_never_certified(tmp_path: Path) -> None:
    """Hostile round 11 (F6): write_manifest over a folder holding a named pipe wrote a
    manifest that verify rejects; now it raises before writing anything."""
    root = tmp_path / "run"
    root.mkdir()
    (root / "a.txt").write_text("a")
    os.mkfifo(root / "zz")
    with pytest.raises(InputError, match="zz, a named pipe, socket or device file"):
        write_manifest(root)
    assert not (root / "manifest.json").exists()


def test_run_again_with_a_smaller_budget_leaves_no_stale_report_figure(
    job: tuple[Path, Path], tmp_path: Path
) -> None:
    """The same job with a smaller budget over an earlier run: its export writes fewer
    scenarios, and the earlier report's figures of the others are removed (the job
    called the search and the export directly and skipped the cleanup the commands do:
    ``report/scenario_003.png`` .. stayed, listed in the manifest)."""
    _, vehicle = job
    out = tmp_path / "out"
    folder = out / "system_b"
    argv = _job_argv(vehicle, out, env="snow")
    argv[argv.index("60")] = "30"  # 3 ranked and exported
    assert main(argv) == 0
    figures = sorted(p.name for p in (folder / "report").glob("scenario_*.png"))
    argv[argv.index("30")] = "20"  # 1 ranked
    assert main(argv) == 0
    exported = len(list((folder / "scenarios").glob("*.xosc")))
    now = sorted(p.name for p in (folder / "report").glob("scenario_*.png"))
    assert len(figures) > exported, (figures, exported)  # the case is the one meant
    assert now == [f"scenario_{i:03d}.png" for i in range(1, exported + 1)], now
    assert main(["verify", str(out)]) == 0 and main(["verify", str(folder)]) == 0


# -- one command at a time per folder (round 11) -----------------------------------------


@pytest.mark.parametrize(
    "command",
    [
        ["export", "--run", "{run}", "--top", "1"],
        ["report", "--run", "{run}"],
        ["simulate", "--catalog", "{run}", "--esmini", "/nonexistent/esmini"],
        [
            "search",
            "--vehicle",
            "system_b",
            "--families",
            "slow_ahead_curve",
            "--environments",
            "snow",
            "--budget",
            "40",
            "--top",
            "2",
            "--out",
            "{run}",
            "--resume",
        ],
        ["nearfield", "--vehicle", "system_a", "--out", "{run}"],
    ],
    ids=lambda c: c[0],
)
def test_a_command_into_a_folder_another_command_writes_is_refused_at_once(
    reported_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], command: list[str]
) -> None:
    """Every command writing into a run folder holds the folder's lock for its whole run:
    a second one is refused before any work (one line naming the folder, exit 2, nothing
    changed). Without it a restore put its start snapshot back over the other command's
    finished output, and a report linked files the folder no longer held."""
    run = tmp_path / "run"
    shutil.copytree(reported_run, run)
    before = tree_state(run)
    capsys.readouterr()
    with held_elsewhere(run):
        assert main([part.format(run=run) for part in command]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(run) in err[0], err
    assert "another sensorgap command is writing this folder" in err[0], err
    assert tree_state(run) == before


def test_a_run_into_an_out_another_command_writes_is_refused(
    job: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A second ``run`` into the same OUT (another vehicle) is refused at once: one
    run's restore deleted the other's finished vehicle folder."""
    src, _ = job
    out = tmp_path / "out"
    shutil.copytree(src, out)
    before = tree_state(out)
    capsys.readouterr()
    with held_elsewhere(out):
        assert main(_job_argv("system_a", out)) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "another sensorgap command is writing" in err[0], err
    assert tree_state(out) == before


def test_export_while_a_report_runs_in_another_process_is_refused(
    reported_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two real processes: while ``report`` writes the run (its restore folder is
    there), ``export --top 1`` is refused; the report finishes and the folder verifies
    (the export used to remove the scenario files the report then linked)."""
    import time

    run = tmp_path / "run"
    shutil.copytree(reported_run, run)
    proc = subprocess.Popen(
        [sys.executable, "-m", "sensorgap", "report", "--run", str(run)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env={**os.environ, "PYTHONPATH": SRC},
    )
    try:
        deadline = time.monotonic() + 60
        while not any(p.name.startswith(RESTORE_PREFIX) for p in run.iterdir()):
            assert proc.poll() is None and time.monotonic() < deadline, "report ended early"
            time.sleep(0.01)
        capsys.readouterr()
        assert main(["export", "--run", str(run), "--top", "1"]) == 2
        err = capsys.readouterr().err
        assert "another sensorgap command is writing this folder" in err, err
    finally:
        _, err = proc.communicate(timeout=120)  # waits, and closes its pipe
        assert proc.returncode == 0, err
    assert main(["verify", str(run)]) == 0
    assert len(list((run / "scenarios").glob("*.xosc"))) == 2


def test_report_into_a_jobs_vehicle_folder_keeps_the_job_certified(
    job: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``report --run OUT/<vehicle>`` certifies OUT again (its manifest lists the vehicle
    folder's files): ``verify OUT`` passes and the job can run into OUT again (before,
    OUT's manifest no longer matched and the rerun was refused). While another command
    holds OUT, the report is refused (it would change what OUT's manifest certifies)."""
    src, vehicle = job
    out = tmp_path / "out"
    shutil.copytree(src, out)
    folder = out / "system_b"
    before = tree_state(out)
    capsys.readouterr()
    with held_elsewhere(out):
        assert main(["report", "--run", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "another sensorgap command is writing" in err[0], err
    assert tree_state(out) == before
    assert main(["report", "--run", str(folder)]) == 0
    assert main(["verify", str(folder)]) == 0 and main(["verify", str(out)]) == 0
    assert not [p for p in out.iterdir() if p.name.startswith(RESTORE_PREFIX)]
    assert main(_job_argv(vehicle, out)) == 0
    assert main(["verify", str(out)]) == 0


@contextmanager
def marked_elsewhere(folder: Path, certifies: bool) -> Iterator[None]:
    """``folder`` marked as another sensorgap command marks the folder it writes
    (``locks.writing``: a shared open-file-description lock on byte 1 when it certifies
    the folder, byte 0 when it writes some files there); one on a second open file
    description conflicts with this process's own."""
    flock = struct.Struct("hhqqi4x")
    fd = os.open(folder, os.O_RDONLY)
    try:
        lock = flock.pack(fcntl.F_RDLCK, os.SEEK_SET, 1 if certifies else 0, 1, 0)
        fcntl.fcntl(fd, fcntl.F_OFD_SETLK, lock)
        yield
    finally:
        os.close(fd)


NESTED_ARGV = [
    ["nearfield", "--vehicle", "system_a", "--resolution", "0.5"],
    ["search", "--vehicle", "system_b", "--families", "slow_ahead_curve", "--budget", "10"],
]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="open-file-description locks")
@pytest.mark.parametrize("where", ["above", "below", "below_writes"])
@pytest.mark.parametrize("argv", NESTED_ARGV, ids=["nearfield", "search"])
def test_an_out_nested_with_a_folder_another_command_is_writing_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str], where: str
) -> None:
    """Hostile round 37: ``nearfield --out P/sub`` while ``corridor --out P`` ran (P being
    certified, no manifest yet) was not refused, nor ``corridor --out Q`` while
    ``nearfield --out Q/sub`` ran; the outer command certified its folder without (or with
    half of) the inner one's files and ``verify`` failed. An --out below a folder another
    command certifies, or above one another command writes (``evaluate``: byte 0), is
    refused, nothing written."""
    outer = tmp_path / "P"
    inner = outer / "a" / "sub"
    inner.mkdir(parents=True)
    before = tree_state(outer)
    with marked_elsewhere(outer if where == "above" else inner, certifies=where != "below_writes"):
        capsys.readouterr()
        assert main([*argv, "--out", str(inner if where == "above" else outer)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "another sensorgap command is writing now" in err[0], err
    if where == "above":
        assert f"{inner}: lies inside {outer}," in err[0], err
    else:
        assert f"{outer}: holds {inner}," in err[0], err
    assert tree_state(outer) == before


@contextmanager
def on_another_thread(block: Any) -> Iterator[None]:
    """The context manager ``block`` entered on another thread of this process, held
    while the ``with`` runs (a second library call running beside this one)."""
    import threading

    entered, leave = threading.Event(), threading.Event()
    failed: list[BaseException] = []

    def hold() -> None:
        try:
            with block:
                entered.set()
                leave.wait(60)
        except BaseException as exc:  # (shown by the assert below)
            failed.append(exc)
            entered.set()

    worker = threading.Thread(target=hold)
    worker.start()
    entered.wait(60)
    try:
        assert not failed, failed
        yield
    finally:
        leave.set()
        worker.join(60)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="open-file-description locks")
@pytest.mark.parametrize("where", ["same", "above", "below"])
def test_a_call_on_another_thread_counts_as_another_command(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], where: str
) -> None:
    """Hostile round 40: two ``find_scenarios`` calls on two threads of one process, on
    nested folders, both ran (the lock and the markers were the process's, shared by its
    threads) and ``verify`` of the outer folder failed; on one folder, one failed mid-work.
    A lock or marker another thread holds is another command's: refused at once."""
    from sensorgap.locks import writing

    outer = tmp_path / "P"
    inner = outer / "sub"
    inner.mkdir(parents=True)
    held = {"same": folder_lock(outer), "above": writing(outer, certifies=True)}
    block = held.get(where, writing(inner, certifies=True))
    out = inner if where == "above" else outer
    before = tree_state(outer)
    with on_another_thread(block):
        capsys.readouterr()
        assert main([*NESTED_ARGV[0], "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "another sensorgap command is writing" in err[0], err
    assert tree_state(outer) == before
    assert main([*NESTED_ARGV[0], "--out", str(out)]) == 0  # once the other call ended


@pytest.mark.parametrize("argv", NESTED_ARGV, ids=["nearfield", "search"])
def test_a_folder_above_only_locked_does_not_refuse_a_nested_out(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], argv: list[str]
) -> None:
    """The fix of round 37 reverted on 2026-11-27 refused an --out below any folder whose
    ``flock`` another process held; ``coverage --out /`` holds the lock of / for a moment
    while it refuses, and a test on another worker was refused ("lies inside /"). A lock
    alone (no writing marker) refuses nothing below it; with --out the command runs."""
    outer = tmp_path / "P"
    inner = outer / "a" / "sub"
    inner.mkdir(parents=True)
    with held_elsewhere(outer), held_elsewhere(tmp_path):
        assert main([*argv, "--out", str(inner)]) == 0
    assert main(["verify", str(inner)]) == 0


def test_a_folder_certified_after_the_first_check_refuses_the_nested_out(
    tmp_path: Path,
) -> None:
    """Hostile round 37's F1 replayed with the markers: ``corridor --out P`` ended (its
    manifest written, its marker gone) after ``nearfield --out P/sub`` passed its first
    check but before that one marked its folder; the near field was written into the
    certified P. The check is repeated once the folder is marked (``locks.
    recheck_when_marked``): refused then, nothing left."""
    from sensorgap.filesio import refuse_inside_certified

    outer = tmp_path / "P"
    inner = outer / "sub"
    outer.mkdir()
    refuse_inside_certified(inner, "nearfield")  # passes: P is no certified folder yet
    atomic_write_text(outer / "corridor.csv", "x\n")
    write_manifest(outer)  # the other command ends
    with (
        pytest.raises(InputError, match=r"lies inside .*P, a certified folder"),
        removed_on_error(inner),
    ):
        (inner / "nearfield.json").write_text("{}", encoding="utf-8")
    assert not inner.exists()
    assert verify_manifest(outer) == []


def test_a_read_only_out_is_named_not_its_restore_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """Hostile round 37: into an existing --out on a read-only file system, the one line
    named the command's random hidden restore folder (``OUT/.sensorgap-restore.h4gw.tmp:
    ... Read-only file system``), not the folder the user gave."""
    import errno
    import tempfile

    out = tmp_path / "ro"
    out.mkdir()
    (out / "mine.txt").write_text("kept", encoding="utf-8")

    def read_only(*args: object, **kwargs: object) -> str:
        path = os.path.join(str(kwargs.get("dir")), f"{kwargs.get('prefix')}x1y2z3w4.tmp")
        raise OSError(errno.EROFS, "Read-only file system", path)

    monkeypatch.setattr(tempfile, "mkdtemp", read_only)
    capsys.readouterr()
    assert (
        main(["nearfield", "--vehicle", "system_a", "--resolution", "0.5", "--out", str(out)]) == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and RESTORE_PREFIX not in err[0], err
    assert err[0].startswith(f"sensorgap: error: {out}: cannot write or read: Read-only"), err
    assert sorted(p.name for p in out.iterdir()) == ["mine.txt"]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="open-file-description locks")
def test_a_certifying_command_looks_at_every_folder_below(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Hostile round 40, F2: the look for other commands' markers below a certifying
    command's folder stopped after 20,000 folders, and ``corridor --out P`` certified a
    half-written P/a/sub beside 20,001 empty folders. It looks at as many folders as a
    certified folder may hold entries (``filesio.MAX_OUT_ENTRIES``); one with more is
    refused. (The cap is lowered here to keep the test small.)"""
    from sensorgap import locks
    from sensorgap.filesio import MAX_OUT_ENTRIES

    assert locks.MAX_MARKED_FOLDERS == MAX_OUT_ENTRIES
    monkeypatch.setattr(locks, "MAX_MARKED_FOLDERS", 30)
    outer = tmp_path / "P"
    for i in range(25):
        (outer / f"d{i:02d}").mkdir(parents=True)
    inner = outer / "z" / "sub"  # walked last (os.walk lists folders in no fixed order)
    inner.mkdir(parents=True)
    with (
        marked_elsewhere(inner, certifies=True),
        pytest.raises(InputError, match="holds "),
        locks.writing(outer, certifies=True),
    ):
        pass
    for i in range(25, 35):
        (outer / f"d{i:02d}").mkdir()
    with (
        pytest.raises(InputError, match="holds more than 30 folders"),
        locks.writing(outer, certifies=True),
    ):
        pass


def test_a_reader_looking_at_a_folder_does_not_refuse_a_writer(tmp_path: Path) -> None:
    """Hostile round 40, R1: ``verify`` looks whether a folder is being written by taking
    a shared lock for an instant (``locks.locked_elsewhere``); a command starting in that
    instant was refused, "another sensorgap command is writing this folder now". A writer
    tries again for ``READER_WAIT_S``; one held longer (a writer) is still refused."""
    import threading
    import time

    from sensorgap.locks import READER_WAIT_S

    held = threading.Event()

    def reader(seconds: float) -> None:
        fd = os.open(tmp_path, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_SH)
            held.set()
            time.sleep(seconds)
        finally:
            os.close(fd)

    look = threading.Thread(target=reader, args=(READER_WAIT_S / 4,))
    look.start()
    held.wait(10)
    with folder_lock(tmp_path):  # taken once the reader let go
        pass
    look.join()
    held.clear()
    stay = threading.Thread(target=reader, args=(READER_WAIT_S * 5,))
    stay.start()
    held.wait(10)
    try:
        with (
            pytest.raises(InputError, match="another sensorgap command is writing"),
            folder_lock(tmp_path),
        ):
            pass
    finally:
        stay.join()
