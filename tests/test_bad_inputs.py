"""Runs the bad-input corpus (tests/bad_inputs/cases.toml, format in its README; cases are
prepared and checked by tests/bad_inputs/harness.py, which benchmarks/bench_corpus.py
shares): every case gives its one-line message on stderr and exit 2, no traceback, nothing
half-written.
Also: an internal error is exit 1 and says so, with a traceback only under --debug."""

from __future__ import annotations

import os
import shutil
from contextlib import nullcontext, redirect_stdout
from pathlib import Path
from typing import Any

import pytest

from sensorgap.cli import main
from tests.bad_inputs.harness import (
    build_finished_run,
    case_cwd,
    case_stdout,
    child_preexec,
    load_cases,
    outcome_problems,
    prepare_case,
)
from tests.forked import run_forked

CASES: list[dict[str, Any]] = load_cases()


def test_corpus_is_large_and_unique() -> None:
    names = [c["name"] for c in CASES]
    assert len(names) >= 120 and len(set(names)) == len(names)
    commands = {c["argv"][0] for c in CASES}
    assert {
        "probe",
        "coverage",
        "nearfield",
        "farfield",
        "search",
        "corridor",
        "schema",
        "run",
        "export",
        "simulate",
        "report",
        "compare",
        "verify",
    } <= commands


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small finished, exported search run with a near-field analysis and a manifest."""
    return build_finished_run(tmp_path_factory.mktemp("run") / "run", main)


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_bad_input(
    case: dict[str, Any],
    tmp_path: Path,
    finished_run: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    prepared = prepare_case(case, tmp_path, finished_run, main)
    argv = prepared.argv
    with case_stdout(case) as stdout:
        if "rlimit_fsize" in case:  # a process of its own: the limit would hold for the tests
            code, err = run_forked(prepared.argv, child_preexec(prepared), prepared.env, stdout)
        else:
            for name, value in prepared.env.items():
                monkeypatch.setenv(name, value)
            closed = case.get("stdout") == "closed"  # as Python starts without fd 1
            with (
                redirect_stdout(None) if closed else nullcontext(),
                redirect_stdout(stdout) if stdout is not None else nullcontext(),
                case_cwd(prepared),
            ):
                try:
                    code = main(argv)
                except SystemExit as exc:  # argparse errors
                    code = int(exc.code or 0)
            err = capsys.readouterr().err
    problems = outcome_problems(prepared, code, err)
    assert not problems, problems[0]


def test_internal_error_is_exit_1_without_traceback(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    import sensorgap.analysis.nearfield as nf

    def boom(*_: Any, **__: Any) -> None:
        raise RuntimeError("synthetic failure")

    monkeypatch.setattr(nf, "write_nearfield", boom)
    argv = ["nearfield", "--vehicle", "system_a", "--out", str(tmp_path / "o")]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "internal error" in err and "Traceback" not in err
    assert "--debug" in err
    assert main(["--debug", *argv]) == 1
    err = capsys.readouterr().err
    assert "Traceback" in err and "synthetic failure" in err


def test_report_into_a_folder_whose_name_is_not_utf8(
    finished_run: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run folder whose name holds a byte that is not UTF-8 (hostile round eight:
    ``report`` ended in an internal error encoding the path): the report is written, the
    byte shown as its ``\\udcXX`` escape, and the folder still verifies."""
    run = Path(os.fsdecode(os.fsencode(tmp_path) + b"/run\xfe"))
    shutil.copytree(finished_run, run)
    assert main(["report", "--run", str(run)]) == 0, capsys.readouterr().err
    md = (run / "report.md").read_text(encoding="utf-8")
    assert "run\\udcfe" in md
    assert main(["verify", str(run)]) == 0
