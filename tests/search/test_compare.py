"""A vs B: the top lists differ and every difference is traced to the sensor setups."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from sensorgap.cli import main
from sensorgap.models import load_system
from sensorgap.search.compare import MARGIN_P, SEES_PD
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
    assert len(rows) >= 2  # the union of the two rankings, duplicates merged
    sensors = {s.name: {x.id for x in s.sensors}
               for s in (load_system("system_a"), load_system("system_b"))}
    one_sided = [r for r in rows if r["critical_for"] not in ("both", "neither")]
    assert one_sided, "the two setups differ, so some scenario must be critical for one only"
    for r in rows:
        pa, pb = r["collision_probability_System A"], r["collision_probability_System B"]
        if r["critical_for"] in ("both", "neither"):
            assert abs(pa - pb) < MARGIN_P
            continue
        worse, better = (("System A", "System B") if r["critical_for"] == "System A"
                         else ("System B", "System A"))
        assert (r[f"collision_probability_{worse}"]
                - r[f"collision_probability_{better}"]) >= MARGIN_P
        # the reason starts with the worse vehicle's missing sensors and their effect ...
        assert r["why"].startswith(f"{worse}: {r['dominant_effect']}:")
        # ... and names the better vehicle's sensors that see the target, with a type
        assert f"| {better} at the same moment sees it with {r['other_sees']}" in r["why"]
        parts = r["other_sees"].split("; ")
        assert parts and all(p.split(" (")[0] in sensors[better] for p in parts)
        assert all(float(re.search(r"Pd ([0-9.]+)", p).group(1)) >= SEES_PD  # type: ignore
                   for p in parts)


def test_markdown_summary_counts_all_rows(runs: Path) -> None:
    md = (runs / "cmp" / "comparison.md").read_text()
    data = json.loads((runs / "cmp" / "comparison.json").read_text())
    counted = sum(int(line.rsplit("|", 2)[1]) for line in md.splitlines()
                  if line.startswith(("| System", "| both", "| neither")))
    assert counted == len(data["rows"])


def test_missing_run_is_one_line_exit_2(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["compare", str(tmp_path / "nope"), str(tmp_path), "--out",
                 str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "ranking.json is missing" in err and len(err.splitlines()) == 1
