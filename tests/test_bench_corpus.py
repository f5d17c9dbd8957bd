"""The corpus benchmark (benchmarks/bench_corpus.py) measures real cases in child processes
and flags a case whose outcome is not the expected one: two cases of the corpus, and one
of them again with a message and an exit code it does not give."""

from __future__ import annotations

import math

from benchmarks.bench_corpus import MAX_CASE_MIB, measure_case, report, select
from tests.bad_inputs.harness import load_cases

#: Two cases that need no finished run: refused before any work (about 1 s each).
NAMES = ("vehicle_unknown_preset", "environment_unknown_preset")


def test_benchmark_measures_cases_and_flags_a_wrong_one() -> None:
    cases = select(load_cases(), name_filter="^(" + "|".join(NAMES) + ")$")
    assert [c["name"] for c in cases] == list(NAMES)
    results = [measure_case(c, None) for c in cases]
    for r in results:
        assert r.problems == [] and r.exit == r.expected == 2, r
        assert r.within and r.ok
        # a Python process that imported sensorgap's command line: tens of MiB at least
        assert 20.0 < r.peak_mib < MAX_CASE_MIB
        assert 0.0 < r.main_s < r.seconds and math.isfinite(r.seconds)
    wrong = {**cases[0], "name": "wrong_message", "message": "no such message"}
    r = measure_case(wrong, None)
    assert not r.ok and "message does not match" in r.problems[0], r
    wrong_exit = {**cases[1], "name": "wrong_exit", "exit": 0}
    r2 = measure_case(wrong_exit, None)
    assert not r2.ok and r2.problems[0].startswith("exit 2"), r2
    text = report([*results, r, r2])
    assert "4 cases: 2 as expected, 2 wrong" in text
    assert "WRONG wrong_message" in text and "WRONG wrong_exit" in text
    assert all(name in text for name in NAMES)


def test_quick_selects_cases_without_a_run() -> None:
    cases = load_cases()
    quick = select(cases, quick=True)
    assert 0 < len(quick) <= 4
    assert all(not any("{run}" in a for a in c["argv"]) for c in quick)
    assert select(cases, name_filter="^unknown_command$")[0]["argv"] == ["teleport"]
