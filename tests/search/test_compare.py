"""``sensorgap compare`` refuses a missing run. The A-vs-B tests (the top lists differ and
every difference is traced to the sensor setups) use the report tests' shared comparison:
tests/report/test_compare_ab.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sensorgap.cli import main


def test_missing_run_is_one_line_exit_2(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert (
        main(["compare", str(tmp_path / "nope"), str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    )
    err = capsys.readouterr().err.strip()
    assert "ranking.json is missing" in err and len(err.splitlines()) == 1


def test_two_versions_of_one_vehicle_are_told_apart(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two runs of vehicles with the same name (System B, and a version of its file whose
    reaction model brakes 0.7 s later): every column, ``critical_for`` value and the report
    name the side, ``System B (A: <run>)`` / ``System B (B: <run>)``; each side's own rank-1
    row is there with its rank and its collision probability, and some rows are critical for
    one side only, named (one side used to overwrite the other's columns, and every row read
    ``critical_for = both``)."""
    import json

    from sensorgap.analysis.nearfield import write_nearfield
    from sensorgap.config.presets import templates_dir
    from sensorgap.models import load_system
    from sensorgap.search.compare import side_labels
    from sensorgap.search.run import run_search

    shipped = (templates_dir() / "reactions.toml").read_text()
    slow = shipped[shipped.index("[reactions.camera_confirmed]") : shipped.index("[reactions.cc")]
    assert "latency_s = 0.3\n" in slow
    (tmp_path / "v2").mkdir()
    (tmp_path / "v2" / "slow.toml").write_text(
        slow.replace("latency_s = 0.3\n", "latency_s = 1.0\n")
    )
    text = (templates_dir() / "vehicles" / "system_b.toml").read_text()
    assert 'reaction = "camera_confirmed"' in text
    v2 = tmp_path / "v2" / "system_b.toml"
    v2.write_text(text.replace('reaction = "camera_confirmed"', 'reaction = "slow.toml"'))
    runs = {"a": tmp_path / "base", "b": tmp_path / "slow_brake"}
    for run, vehicle, seed in zip(runs.values(), ("system_b", v2), (5, 6), strict=True):
        run_search(
            vehicle,
            ["cut_out_reveal"],
            ["fog_50"],
            60,
            seed,
            3,
            run,
            strategy="lhs",
            progress=False,
        )
        # each run's own near field: the two comparisons below take it from the run
        # instead of computing it each time (4 x 1.6 s of CPU)
        write_nearfield(load_system(vehicle), run / "nearfield")
    out = tmp_path / "cmp"
    assert main(["compare", str(runs["a"]), str(runs["b"]), "--out", str(out)]) == 0
    capsys.readouterr()
    la, lb = "System B (A: base)", "System B (B: slow_brake)"
    assert side_labels("System B", "System B", runs["a"], runs["b"]) == (la, lb)
    data = json.loads((out / "comparison.json").read_text())
    cols = data["columns"]
    for key in ("rank", "collision_probability", "impact_speed_kmh", "class"):
        assert f"{key}_{la}" in cols and f"{key}_{lb}" in cols
        assert f"{key}_System B" not in cols
    rows = {r["scenario_id"]: r for r in data["rows"]}
    for label, run in zip((la, lb), runs.values(), strict=True):
        best = json.loads((run / "ranking.json").read_text())["ranking"][0]
        row = rows[best["scenario_id"]]
        assert row[f"rank_{label}"] == 1
        assert row[f"collision_probability_{label}"] == pytest.approx(
            best["collision_probability"], abs=1e-9
        )
        assert best["collision_probability"] > 0.05
    who = {r["critical_for"] for r in data["rows"]}
    assert who <= {la, lb, "both", "neither"}
    assert {la, lb} <= who  # the two setups differ: some rows are critical for one only
    for r in data["rows"]:
        if r["critical_for"] in (la, lb):
            other = lb if r["critical_for"] == la else la
            assert r["why"].startswith(f"{r['critical_for']}: ")
            mine = r[f"collision_probability_{r['critical_for']}"]
            theirs = r[f"collision_probability_{other}"]
            # higher by 0.1, or the other below what a ranking keeps (1e-6)
            assert mine >= 1e-6 and (mine - theirs >= 0.1 or theirs < 1e-6)
    # the same vehicle but for its reaction model: the maps and far field are computed
    # once and written for both sides (compare_maps._sensing), each with its own
    # vehicle file's digest, which an assessor traces them to
    from sensorgap.provenance import sha256_of

    vehicles = {"a": templates_dir() / "vehicles" / "system_b.toml", "b": v2}
    for tag, vehicle in vehicles.items():
        for piece in ("coverage/car_fog_50", "farfield/fog_50"):
            summary = json.loads((out / f"{tag}_system_b" / piece / "summary.json").read_text())
            assert summary["vehicle_sha256"] == sha256_of(vehicle), (tag, piece)
    a_map, b_map = (
        np.load(out / f"{t}_system_b" / "coverage" / "car_fog_50" / "coverage.npz") for t in "ab"
    )
    assert np.array_equal(a_map["pd"], b_map["pd"])
    md = (out / "report.md").read_text()
    assert f"# sensorgap: {la} vs {lb}" in md and f"| rank {la} | rank {lb} |" in md
    assert f"- **{la}:** run folder base;" in md
    # a rerun into its own earlier folder goes on (report --compare writes the same files
    # as compare; another command's certified folder is refused: tests/cli/test_out_folders)
    capsys.readouterr()
    assert main(["report", "--compare", str(runs["a"]), str(runs["b"]), "--out", str(out)]) == 0
    assert main(["verify", str(out)]) == 0


def test_side_labels() -> None:
    """Vehicles of different names keep them; equal names, or a name that is another value
    of ``critical_for``, get the side's tag and run folder (odd characters replaced)."""
    from sensorgap.search.compare import side_labels

    assert side_labels("System A", "System B", Path("r1"), Path("r2")) == ("System A", "System B")
    assert side_labels("both", "X", Path("/t/r|1"), Path("/t/r\n2")) == (
        "both (A: r_1)",
        "X (B: r_2)",
    )
    assert side_labels("V", "V", Path("/t/run"), Path("/u/run")) == ("V (A: run)", "V (B: run)")


def test_run_notes_carry_a_searchs_own_note(tmp_path: Path) -> None:
    """Hostile round fifteen: a comparison of two runs none of whose candidates was
    feasible wrote empty tables that read as "no gap in either"; each run's search note
    (summary.json) now goes with it (comparison.json ``run_notes``, comparison.md, the
    report's "What is compared", the printed lines)."""
    import json

    from sensorgap.search.compare import run_notes
    from sensorgap.search.possible import no_feasible_note

    a, b, c = (tmp_path / n for n in ("a", "b", "c"))
    for folder in (a, b, c):
        folder.mkdir()
    note = no_feasible_note(80, {"starts within reach: ...": 61})
    (a / "summary.json").write_text(json.dumps({"note": note}))
    (b / "summary.json").write_text(json.dumps({"candidates": 80}))  # a run with no note
    assert run_notes(a, b) == [f"a: {note}"]
    (c / "summary.json").write_text("{not json")
    assert run_notes(c, a) == [f"a: {note}"]  # an unreadable summary adds nothing
    assert "says nothing about the sensors" in run_notes(a, a)[1]


def test_critical_for_counts_a_side_from_what_a_ranking_keeps() -> None:
    """A side counts from P(collision) 1e-6 (``RANK_MIN_P``): B's glare row at 0.0097
    against A's 1.4e-36 (System B's glare search of 2026-11-27) is B's alone, where it
    read ``both`` when any P > 0 counted; two counting sides within 0.1 are ``both``."""
    from sensorgap.search.compare import critical_for

    assert critical_for(0.0097, 1.4e-36, "A", "B", 0.1) == "A"
    assert critical_for(1.4e-36, 0.0097, "A", "B", 0.1) == "B"
    assert critical_for(0.05, 0.02, "A", "B", 0.1) == "both"
    assert critical_for(5e-7, 0.0, "A", "B", 0.1) == "neither"
    assert critical_for(0.9, 0.5, "A", "B", 0.1) == "A"
    assert critical_for(0.5, 0.9, "A", "B", 0.1) == "B"


@pytest.mark.parametrize(
    ("rows", "field", "why"),
    [
        ("nan,0.5\n", "row 2.s", "expected a length >= 0 \\(m\\), got 'nan'"),
        ("1,0.5\n-5,0.5\n", "row 3.s", "expected a length >= 0 \\(m\\), got '-5'"),
        ("1,5\n", "row 2.pd", "expected a probability 0..1, got '5'"),
        ("1,0.5\n1,0.6\n", "row 3.s", "distances must increase row by row"),
        ("1\n", "row 2.pd", "expected a probability 0..1, got 'None'"),
    ],
)
def test_a_far_field_profile_is_checked_before_it_is_plotted(
    tmp_path: Path, rows: str, field: str, why: str
) -> None:
    """Hostile round 25: compare plotted a run's farfield.csv as it was (NaN distances,
    negative ones, a Pd of 5); each row's s is a finite length >= 0, increasing, and its
    pd a probability, else one line naming the row and column."""
    from sensorgap.errors import InputError
    from sensorgap.report.compare import _profile

    path = tmp_path / "farfield.csv"
    path.write_text("s,pd\n" + rows, encoding="utf-8")
    with pytest.raises(InputError, match=f"{field}: {why}"):
        _profile(path)
    path.write_text("s,pd\n0.5,0\n1.0,1\n", encoding="utf-8")
    s, pd = _profile(path)
    assert s.tolist() == [0.5, 1.0] and pd.tolist() == [0.0, 1.0]


def test_a_rerun_into_its_own_comparison_removes_the_earlier_ones_files(tmp_path: Path) -> None:
    """Hostile round 26: a comparison written again into its own earlier --out kept the
    earlier one's pieces (a near field computed before the run had its own, the folders
    of two runs given the other way round) beside the new ones, and certified them. The
    files the earlier manifest lists go first; a file of the user's stays."""
    from sensorgap.filesio import write_manifest
    from sensorgap.report.compare import clear_earlier_comparison

    out = tmp_path / "cmp"
    (out / "a_system_b" / "nearfield").mkdir(parents=True)
    (out / "a_system_b" / "nearfield" / "nearfield.json").write_text("{}")
    (out / "comparison.json").write_text("{}")
    (out / "report.md").write_text("earlier")
    write_manifest(out)
    (out / "my_notes.txt").write_text("the user's")
    removed = clear_earlier_comparison(out)
    assert removed == ["a_system_b/nearfield/nearfield.json", "comparison.json", "report.md"]
    left = sorted(p.relative_to(out).as_posix() for p in out.rglob("*"))
    assert left == ["manifest.json", "my_notes.txt"]
    # a folder certified by another command is left alone (the CLI refuses it before)
    other = tmp_path / "nf"
    other.mkdir()
    (other / "nearfield.json").write_text("{}")
    write_manifest(other)
    assert clear_earlier_comparison(other) == [] and (other / "nearfield.json").is_file()
