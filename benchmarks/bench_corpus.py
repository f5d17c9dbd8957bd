"""Bad-input corpus benchmark (issue #18): every case of ``tests/bad_inputs/cases.toml``
run through the command line in a fresh child process; per case its wall time, the
child's peak resident memory (``resource.getrusage(...).ru_maxrss``: the process and,
added, any process it started) and whether its outcome is the one the corpus expects
(exit code, one ``sensorgap: error:`` line matching ``message``, nothing written: the
checks of ``tests/test_bad_inputs.py``, from the shared ``tests/bad_inputs/harness.py``),
against the per-case bounds of docs/limits.md (4 GiB, "a few minutes": ``MAX_CASE_S``).

``python benchmarks/run.py corpus`` (every case: about 10 minutes on the
2-core machine) or ``python benchmarks/bench_corpus.py [--quick] [--filter REGEX]``
(``--quick``: a few cases that need no finished run, seconds; ``--filter``: the cases
whose name matches). The exit code of the latter is 1 when any case is wrong or beyond a
bound.

A child's ``ru_maxrss`` is at least its parent's resident size when it was started (Linux
carries the parent's high-water mark over ``exec``), so this parent stays small: it
imports nothing of sensorgap, and the commands a case's setup needs (the finished run,
``existing_search``) run in children too. The parent's own size is printed.
"""

from __future__ import annotations

import json
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
sys.path.insert(0, str(ROOT))

from benchmarks.common import max_rss_mib, table  # noqa: E402
from tests.bad_inputs.harness import (  # noqa: E402
    build_finished_run,
    case_stdout,
    child_preexec,
    load_cases,
    needs_run,
    outcome_problems,
    prepare_case,
)

#: Per-case bounds (docs/limits.md: the worst accepted input within about 4 GiB and "a
#: few minutes" on the 2-core machine; a refusal is checked before any work, so it must
#: stay far below both): peak MiB and wall seconds of one case.
MAX_CASE_MIB = 4096.0
MAX_CASE_S = 180.0
#: A case still running after this is killed and reported (a hang, not a measurement).
KILL_S = 900.0
#: ``--quick``: this many cases, the first in the corpus that need no finished run.
QUICK_CASES = 4

CHILD = r"""
import json, resource, sys, time
t0 = time.perf_counter()
from sensorgap.cli import main
try:
    code = main(sys.argv[2:])
except SystemExit as exc:  # argparse errors
    code = int(exc.code or 0)
dt = time.perf_counter() - t0
me = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
kids = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
with open(sys.argv[1], "w") as f:
    json.dump({"exit": code, "main_s": dt, "self_mib": me, "children_mib": kids}, f)
"""


@dataclass
class CaseResult:
    """One case measured: its outcome, wall seconds (the whole child process, start-up
    included; ``main_s``: importing the command line and running it), peak MiB (the child's
    ``ru_maxrss`` plus its own children's) and what is wrong with its outcome."""

    name: str
    command: str
    exit: int
    expected: int
    seconds: float
    main_s: float
    peak_mib: float
    problems: list[str] = field(default_factory=list)

    @property
    def within(self) -> bool:
        """Within the per-case bounds (``MAX_CASE_S``, ``MAX_CASE_MIB``)."""
        return self.seconds <= MAX_CASE_S and self.peak_mib <= MAX_CASE_MIB

    @property
    def ok(self) -> bool:
        """The expected outcome, within the bounds."""
        return not self.problems and self.within


def _env() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": str(SRC)}


def run_cli_child(argv: list[str]) -> int:
    """``sensorgap argv`` in a child process (a case's setup); its exit code."""
    proc = subprocess.run(
        [sys.executable, "-m", "sensorgap", *argv],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=_env(),
        timeout=KILL_S,
        check=False,
    )
    return proc.returncode


def measure_case(case: dict[str, Any], finished_run: Path | None) -> CaseResult:
    """Prepare ``case`` (``tests/bad_inputs/harness.py``) in a scratch folder, run it in a
    fresh child process and check its outcome as the corpus test does."""
    with tempfile.TemporaryDirectory(prefix="bench_corpus_") as d:
        prepared = prepare_case(case, Path(d), finished_run, run_cli_child)
        result_file = Path(d) / "result.json"
        with case_stdout(case) as stdout:
            t0 = time.perf_counter()
            try:
                proc = subprocess.run(
                    # -P: no working directory on sys.path, as for the console script (in a
                    # deleted one Python 3.13's import of pydantic_core raised SystemError)
                    [sys.executable, "-P", "-c", CHILD, str(result_file), *prepared.argv],
                    stdout=subprocess.DEVNULL if stdout is None else stdout,
                    stderr=subprocess.PIPE,
                    env={**_env(), **prepared.env},
                    preexec_fn=child_preexec(prepared),
                    timeout=KILL_S,
                    check=False,
                )
                returncode, err = proc.returncode, proc.stderr.decode("utf-8", "replace")
            except subprocess.TimeoutExpired:
                returncode, err = -9, f"killed after {KILL_S:g} s"
            seconds = time.perf_counter() - t0
        died = not result_file.is_file()
        r = (
            {"exit": returncode, "main_s": float("nan"), "self_mib": float("nan")}
            if died
            else json.loads(result_file.read_text())
        )
        problems = outcome_problems(prepared, int(r["exit"]), err)
        if died:  # killed (a signal, the time limit) or failed before reporting
            problems.insert(0, f"the child process ended with {returncode}: {err[-300:]}")
    return CaseResult(
        case["name"],
        case["argv"][0],
        int(r["exit"]),
        int(case["exit"]),
        seconds,
        float(r["main_s"]),
        float(r["self_mib"]) + float(r.get("children_mib", 0.0)),
        problems,
    )


def select(
    cases: list[dict[str, Any]], quick: bool = False, name_filter: str | None = None
) -> list[dict[str, Any]]:
    """The cases to run: those whose name matches ``name_filter`` (a regular expression,
    ``re.search``), and with ``quick`` only the first ``QUICK_CASES`` of them that need no
    finished run and no search of their own."""
    chosen = [c for c in cases if name_filter is None or re.search(name_filter, c["name"])]
    if quick:
        chosen = [
            c for c in chosen if not needs_run(c) and "existing_search" not in c.get("setup", [])
        ][:QUICK_CASES]
    return chosen


def measure(cases: list[dict[str, Any]], progress: bool = True) -> list[CaseResult]:
    """Every case of ``cases`` measured in order (the finished run the ``{run}`` cases
    copy is built first, in child processes, when one needs it); a line per case on
    stderr with ``progress``."""
    results = []
    with tempfile.TemporaryDirectory(prefix="bench_corpus_run_") as d:
        finished = (
            build_finished_run(Path(d) / "run", run_cli_child)
            if any(needs_run(c) for c in cases)
            else None
        )
        for i, case in enumerate(cases):
            r = measure_case(case, finished)
            results.append(r)
            if progress:
                print(
                    f"[{i + 1}/{len(cases)}] {r.name}: exit {r.exit}, {r.seconds:.2f} s, "
                    f"{r.peak_mib:.0f} MiB{'' if r.ok else ' <- ' + '; '.join(r.problems)}",
                    file=sys.stderr,
                    flush=True,
                )
    return results


def report(results: list[CaseResult], parent_mib: float | None = None) -> str:
    """The Markdown table of ``results``, a summary line, the five slowest and the five
    largest cases, and every case whose outcome is wrong."""
    rows = [
        [
            r.name,
            r.command,
            str(r.exit),
            str(r.expected),
            f"{r.seconds:.2f}",
            f"{r.main_s:.2f}",
            f"{r.peak_mib:.0f}",
            "yes" if r.within else "no",
            "ok" if not r.problems else "WRONG",
        ]
        for r in results
    ]
    headers = [
        "case",
        "command",
        "exit",
        "expected",
        "time [s]",
        "import+main [s]",
        "peak [MiB]",
        f"<= {MAX_CASE_S:g} s, {MAX_CASE_MIB / 1024:g} GiB",
        "outcome",
    ]
    wrong = [r for r in results if r.problems]
    beyond = [r for r in results if not r.within]
    secs = [r.seconds for r in results]
    peaks = [r.peak_mib for r in results]
    slow = max(results, key=lambda r: r.seconds)
    big = max(results, key=lambda r: r.peak_mib)
    summary = (
        f"{len(results)} cases: {len(results) - len(wrong)} as expected, {len(wrong)} wrong, "
        f"{len(results) - len(beyond)} within the bounds; time median {statistics.median(secs):.2f}"
        f" s, max {slow.seconds:.2f} s ({slow.name}); peak median "
        f"{statistics.median(peaks):.0f} MiB, max {big.peak_mib:.0f} MiB ({big.name})"
    )
    parts = [
        "Bad-input corpus (tests/bad_inputs/cases.toml), each case in a fresh child process; "
        "time: the whole process (start-up included), import+main: sensorgap.cli imported and run",
        "",
        table(headers, rows),
        "",
        summary,
        "slowest: "
        + ", ".join(
            f"{r.name} {r.seconds:.2f} s" for r in sorted(results, key=lambda r: -r.seconds)[:5]
        ),
        "largest: "
        + ", ".join(
            f"{r.name} {r.peak_mib:.0f} MiB" for r in sorted(results, key=lambda r: -r.peak_mib)[:5]
        ),
    ]
    if parent_mib is not None:
        parts.append(
            f"(this benchmark's own process: {parent_mib:.0f} MiB, a floor of each child's "
            "ru_maxrss)"
        )
    parts += [f"WRONG {r.name}: {r.problems[0][:300]}" for r in wrong]
    return "\n".join(parts) + "\n"


def run(quick: bool = False, name_filter: str | None = None) -> str:
    """Measure the selected cases (``select``) and return the report (``report``)."""
    results = measure(select(load_cases(), quick, name_filter))
    if not results:
        return "no case selected\n"
    return report(results, max_rss_mib())


def main(argv: list[str]) -> int:
    """``[--quick] [--filter REGEX]``: print the report; 1 if any case is wrong or beyond a
    bound."""
    name_filter = argv[argv.index("--filter") + 1] if "--filter" in argv else None
    results = measure(select(load_cases(), "--quick" in argv, name_filter))
    if not results:
        print("no case selected", file=sys.stderr)
        return 2
    print(report(results, max_rss_mib()))
    return 0 if all(r.ok for r in results) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
