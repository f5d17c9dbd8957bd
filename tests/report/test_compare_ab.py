"""A vs B: the top lists differ and every difference is traced to the sensor setups. On the
report tests' shared comparison (tests/report/conftest.py ``compared``: a System A run
against a System B run), built once per session; moved here from
tests/search/test_compare.py, which built two search runs and their comparison of its own."""

from __future__ import annotations

import json
import re
from pathlib import Path

from sensorgap.models import load_system
from sensorgap.search.compare import MARGIN_P, SEES_PD
from sensorgap.search.ranking import RANK_MIN_P


def test_top_lists_differ(compared: Path) -> None:
    run_a, run_b = compared.parent / "system_a", compared.parent / "system_b"
    a = (run_a / "ranking.csv").read_bytes()
    b = (run_b / "ranking.csv").read_bytes()
    assert a != b
    ids_a = {r["scenario_id"] for r in json.loads((run_a / "ranking.json").read_text())["ranking"]}
    ids_b = {r["scenario_id"] for r in json.loads((run_b / "ranking.json").read_text())["ranking"]}
    assert ids_a != ids_b


def test_every_difference_names_the_sensors_of_both_setups(compared: Path) -> None:
    data = json.loads((compared / "comparison.json").read_text())
    rows = data["rows"]
    assert len(rows) >= 2  # the union of the two rankings, duplicates merged
    sensors = {
        s.name: {x.id for x in s.sensors}
        for s in (load_system("system_a"), load_system("system_b"))
    }
    one_sided = [r for r in rows if r["critical_for"] not in ("both", "neither")]
    assert one_sided, "the two setups differ, so some scenario must be critical for one only"
    for r in rows:
        pa, pb = r["collision_probability_System A"], r["collision_probability_System B"]
        if r["critical_for"] == "both":
            assert abs(pa - pb) < MARGIN_P and min(pa, pb) >= RANK_MIN_P
            continue
        if r["critical_for"] == "neither":
            assert max(pa, pb) < RANK_MIN_P
            continue
        worse, better = (
            ("System A", "System B")
            if r["critical_for"] == "System A"
            else ("System B", "System A")
        )
        p_worse = r[f"collision_probability_{worse}"]
        p_better = r[f"collision_probability_{better}"]
        assert p_worse >= RANK_MIN_P
        assert p_worse - p_better >= MARGIN_P or p_better < RANK_MIN_P
        # the reason starts with the worse vehicle's missing sensors and their effect ...
        assert r["why"].startswith(f"{worse}: {r['dominant_effect']}:")
        # ... and names the better vehicle's sensors that see the target, with a type, or
        # says that none does at that moment (the better one then confirms it at another
        # step, e.g. once the lead car that hid it for both has moved away)
        if not r["other_sees"]:
            assert f"| {better} at the same moment sees it with no sensor above Pd" in r["why"]
            # ... and then when it confirms it and with which sensors
            assert re.search(
                r"; it confirms it at \d+\.\d\d s \(median\) with \w|; it does not confirm it",
                r["why"],
            ), r["why"]
            continue
        assert f"| {better} at the same moment sees it with {r['other_sees']}" in r["why"]
        parts = r["other_sees"].split("; ")
        assert parts and all(p.split(" (")[0] in sensors[better] for p in parts)
        assert all(
            float(re.search(r"Pd ([0-9.]+)", p).group(1)) >= SEES_PD  # type: ignore
            for p in parts
        )


def test_markdown_summary_counts_all_rows(compared: Path) -> None:
    md = (compared / "comparison.md").read_text()
    data = json.loads((compared / "comparison.json").read_text())
    counted = sum(
        int(line.rsplit("|", 2)[1])
        for line in md.splitlines()
        if line.startswith(("| System", "| both", "| neither"))
    )
    assert counted == len(data["rows"])
