"""A vs B: the top lists differ and every difference is traced to the sensor setups."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from sensorgap.cli import main
from sensorgap.models import load_system
from sensorgap.search.compare import MARGIN_DECADES, SEES_PD
from sensorgap.search.run import run_search

FAMILIES = ["stopped_rural_curve", "crossing_pedestrian"]
ENVS = ["clear", "glare_front_right", "fog_50"]


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("ab")
    for v in ("system_a", "system_b"):
        run_search(v, FAMILIES, ENVS, 1200, 3, 5, root / v, strategy="lhs", progress=False)
    assert main([
        "compare", str(root / "system_a"), str(root / "system_b"), "--out", str(root / "cmp")
    ]) == 0
    return root


def test_top_lists_differ(runs: Path) -> None:
    a = (runs / "system_a" / "ranking.csv").read_bytes()
    b = (runs / "system_b" / "ranking.csv").read_bytes()
    assert a != b
    ids_a = {r["scenario_id"] for r in json.loads((runs / "system_a" / "ranking.json")
                                                  .read_text())["ranking"]}
    ids_b = {r["scenario_id"] for r in json.loads((runs / "system_b" / "ranking.json")
                                                  .read_text())["ranking"]}
    assert ids_a != ids_b


def test_every_difference_names_the_sensors_of_both_setups(runs: Path) -> None:
    data = json.loads((runs / "cmp" / "comparison.json").read_text())
    rows = data["rows"]
    assert len(rows) >= 6  # the union of two top-5 lists, duplicates merged
    sensors = {s.name: {x.id for x in s.sensors}
               for s in (load_system("system_a"), load_system("system_b"))}
    one_sided = [r for r in rows if r["critical_for"] != "both"]
    assert one_sided, "the two setups differ, so some scenario must be critical for one only"
    for r in rows:
        ra, rb = r["log10_risk_System A"], r["log10_risk_System B"]
        if r["critical_for"] == "both":
            assert abs(ra - rb) < MARGIN_DECADES
            continue
        worse, better = (("System A", "System B") if r["critical_for"] == "System A"
                         else ("System B", "System A"))
        assert r[f"log10_risk_{worse}"] - r[f"log10_risk_{better}"] >= MARGIN_DECADES
        # the reason starts with the worse vehicle's missing sensors and their effect ...
        assert r["why"].startswith(f"{worse}: {r['dominant_effect']}:")
        # ... and names the better vehicle's sensors that see the target, with a type
        assert f"| {better} at the same moment sees it with {r['other_sees']}" in r["why"]
        parts = r["other_sees"].split("; ")
        assert parts and all(p.split(" (")[0] in sensors[better] for p in parts)
        assert all(float(p.split("Pd ")[1].rstrip(")")) >= SEES_PD for p in parts)


def test_markdown_summary_counts_all_rows(runs: Path) -> None:
    md = (runs / "cmp" / "comparison.md").read_text()
    data = json.loads((runs / "cmp" / "comparison.json").read_text())
    counted = sum(int(line.rsplit("|", 2)[1]) for line in md.splitlines()
                  if line.startswith("| System") or line.startswith("| both"))
    assert counted == len(data["rows"])


def test_missing_run_is_one_line_exit_2(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["compare", str(tmp_path / "nope"), str(tmp_path), "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "ranking.json is missing" in err and len(err.splitlines()) == 1
