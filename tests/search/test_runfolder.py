"""The run folder is a contract (issue #14 item 3): a search records its inputs, and
export, report, compare and evaluate rebuild from them, not from presets of the same name.

One small search (system_b, a custom family outside templates, a custom environments file
whose ``clear`` is 50 m fog; 40 candidates) serves every test here."""

from __future__ import annotations

import hashlib
import json
import re
import shutil
from pathlib import Path
from typing import Any

import pytest

from sensorgap.cli import main
from sensorgap.config.presets import roads_dir, templates_dir
from sensorgap.errors import InputError
from sensorgap.search.compare import write_comparison
from sensorgap.search.run import run_search
from sensorgap.search.runfolder import open_run

#: The custom family: a renamed copy of cut_in_left with narrower ranges (chosen so 40
#: candidates find sensor-critical scenarios).
NARROW = [
    ("ego_s0_m = [50.0, 700.0]", "ego_s0_m = [100.0, 250.0]"),
    ("ego_speed_m_s = [15.0, 36.0]", "ego_speed_m_s = [20.0, 26.0]"),
    # a slow car (below camera_confirmed's 5 m/s: B's radar does not confirm it) merging
    # ahead in the environments file's fog, which B's cameras see late
    ("target_speed_m_s = [10.0, 36.0]", "target_speed_m_s = [3.0, 4.5]"),
    ("dx0_m = [-15.0, 60.0]", "dx0_m = [70.0, 100.0]"),
    ("lc_start_s = [0.5, 6.0]", "lc_start_s = [0.5, 1.5]"),
    ("lc_duration_s = [2.5, 6.0]", "lc_duration_s = [4.5, 6.0]"),
]


def _sha(p: Path) -> str:
    return hashlib.sha256(p.read_bytes()).hexdigest()


def _evaluate_argv(run: Path, row: dict[str, Any]) -> list[str]:
    """``sensorgap evaluate`` of the ranked ``row`` of ``run`` (its sun and parameters),
    without ``--out``."""
    argv = ["evaluate", "--run", str(run), "--family", "my_cut_in", "--environment", "clear"]
    if row.get("sun_azimuth_deg") is not None:
        argv += ["--sun", f"{row['sun_azimuth_deg']!r}/{row['sun_elevation_deg']!r}"]
    return argv + [
        f"--param={k[2:]}={v}"
        for k, v in row.items()
        if k.startswith("p_") and k[2:] not in ("never_confirmed", "undetected_end")
    ]


@pytest.fixture(scope="module")
def custom(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """Custom inputs and the run folder searched with them (exported and reported)."""
    base = tmp_path_factory.mktemp("custom")
    text = (templates_dir() / "environments.toml").read_text(encoding="utf-8")
    fog = re.sub(
        r"(\[environments\.clear\]\n(?:.*\n)*?)visibility_m = 23000\.0",
        r"\1visibility_m = 50.0",
        text,
        count=1,
    )
    assert fog != text
    envs = base / "my_envs.toml"
    envs.write_text(fog, encoding="utf-8")
    fam = (templates_dir() / "scenarios" / "cut_in_left.toml").read_text(encoding="utf-8")
    for old, new in NARROW:
        assert old in fam
        fam = fam.replace(old, new)
    (base / "fams").mkdir()
    family = base / "fams" / "my_cut_in.toml"
    family.write_text(fam, encoding="utf-8")
    run = base / "runs" / "run"
    run_search(
        "system_b",
        [str(family)],
        ["clear"],
        40,
        3,
        3,
        run,
        strategy="lhs",
        environments_file=envs,
        progress=False,
    )
    return {"base": base, "envs": envs, "family": family, "run": run}


@pytest.fixture(scope="module")
def exported(custom: dict[str, Path]) -> Path:
    """The run exported (maneuver style) into itself."""
    run = custom["run"]
    assert main(["export", "--run", str(run)]) == 0
    return run


def test_search_records_every_input(custom: dict[str, Path]) -> None:
    run = custom["run"]
    info = json.loads((run / "run.json").read_text(encoding="utf-8"))
    inputs = info["inputs"]
    assert inputs["environments"]["path"] == str(custom["envs"].resolve())
    assert inputs["families"]["my_cut_in"]["path"] == str(custom["family"].resolve())
    assert inputs["families"]["my_cut_in"]["road"] == "motorway_r500"
    assert inputs["vehicle"]["path"].endswith("system_b.toml")
    assert inputs["reaction"]["name"]  # system_b names a preset of reactions.toml
    for key in ("vehicle", "environments", "targets", "reaction", "friction"):
        e = inputs[key]
        copy = run / e["copy"]
        assert copy.read_bytes() == Path(e["path"]).read_bytes()
        assert _sha(copy) == e["sha256"] == _sha(Path(e["path"]))
    road = inputs["roads"]["motorway_r500"]
    assert (run / road["copy"]).read_bytes() == Path(road["path"]).read_bytes()
    rows = json.loads((run / "ranking.json").read_text(encoding="utf-8"))["ranking"]
    assert rows and {r["family"] for r in rows} == {"my_cut_in"}


def test_export_uses_the_custom_environment_and_family(exported: Path) -> None:
    files = sorted((exported / "scenarios").glob("*.xosc"))
    assert files
    for f in files:
        fogs = re.findall(r'<Fog visualRange="([0-9.]+)"', f.read_text(encoding="utf-8"))
        assert fogs == ["50"], f  # the custom clear, not the preset's 23000 m
    index = json.loads((exported / "catalog.json").read_text(encoding="utf-8"))
    assert {s["family"] for s in index["scenarios"]} == {"my_cut_in"}


def test_report_uses_the_recorded_inputs(exported: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    assert main(["report", "--run", str(exported)]) == 0
    md = (exported / "report.md").read_text(encoding="utf-8")
    assert "### 1. my_cut_in in clear" in md
    assert "recorded in the run: inputs/environments/my_envs.toml" in md
    rows = [ln for ln in md.splitlines() if ln.startswith("| clear |")]
    clear = [ln for ln in rows if "StVO" not in ln]  # the environment table
    assert clear and clear[0].split("|")[4].strip() == "50"  # visibility [m]
    # the lawful-speed table: the recorded 50 m 'clear' bounds the ego speed, not 23 km
    assert any("StVO" in ln and "visibility 50 m" in ln for ln in rows)


def test_compare_and_evaluate_rebuild_the_ranked_numbers(
    custom: dict[str, Path], tmp_path: Path
) -> None:
    run = custom["run"]
    rows = json.loads((run / "ranking.json").read_text(encoding="utf-8"))["ranking"]
    # the cross-evaluation ``sensorgap compare`` writes (comparison.json), without the maps
    # it completes (their recorded inputs: tests/search/test_compare_maps.py)
    write_comparison(run, run, tmp_path / "cmp")
    cmp = json.loads((tmp_path / "cmp" / "comparison.json").read_text(encoding="utf-8"))
    # the same vehicle on both sides: each side's columns by its tag and run folder
    la, lb = f"System B (A: {run.name})", f"System B (B: {run.name})"
    p = {r["scenario_id"]: r[f"collision_probability_{la}"] for r in cmp["rows"]}
    assert all(r[f"collision_probability_{lb}"] == p[r["scenario_id"]] for r in cmp["rows"])
    assert {r["family"] for r in cmp["rows"]} == {"my_cut_in"}
    for r in rows:  # exact numbers of the search, recomputed from the recorded inputs
        assert p[r["scenario_id"]] == pytest.approx(r["collision_probability"], abs=1e-12)
    r = rows[0]
    assert main([*_evaluate_argv(run, r), "--out", str(tmp_path / "ev")]) == 0
    ev = json.loads((tmp_path / "ev" / "evaluation.json").read_text(encoding="utf-8"))
    assert ev["scenario_id"] == r["scenario_id"]
    assert ev["metrics"]["collision_probability"] == pytest.approx(
        r["collision_probability"], abs=1e-12
    )


def test_a_copied_run_rebuilds_identically_after_the_templates_changed(
    exported: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    assert main(["report", "--run", str(exported)]) == 0
    copy = tmp_path / "elsewhere" / exported.name
    shutil.copytree(exported, copy)
    for name in ("scenarios", "roads", "report"):
        shutil.rmtree(copy / name)
    for name in ("catalog.json", "report.md", "report.html", "manifest.json"):
        (copy / name).unlink(missing_ok=True)
    # the shipped presets change after the run: vehicles, environments, targets, roads
    tdir = tmp_path / "templates"
    shutil.copytree(templates_dir(), tdir)
    env = tdir / "environments.toml"
    env.write_text(env.read_text(encoding="utf-8").replace("23000.0", "9000.0"), encoding="utf-8")
    veh = tdir / "vehicles" / "system_b.toml"
    veh.write_text(veh.read_text(encoding="utf-8") + "\n# changed\n", encoding="utf-8")
    monkeypatch.setenv("SENSORGAP_TEMPLATES", str(tdir))
    # the shipped roads without the run's (motorway_r500): only another road is shipped
    other = tmp_path / "other_roads"
    other.mkdir()
    shutil.copyfile(roads_dir() / "rural_two_lane.xodr", other / "rural_two_lane.xodr")
    monkeypatch.setenv("SENSORGAP_ROADS", str(other))
    assert main(["export", "--run", str(copy)]) == 0
    assert main(["report", "--run", str(copy)]) == 0
    xosc = sorted(p.name for p in (exported / "scenarios").glob("*.xosc"))
    assert xosc == sorted(p.name for p in (copy / "scenarios").glob("*.xosc"))
    for name in xosc:
        assert (copy / "scenarios" / name).read_bytes() == (
            exported / "scenarios" / name
        ).read_bytes()
    assert (copy / "roads" / "motorway_r500.xodr").read_bytes() == (
        exported / "roads" / "motorway_r500.xodr"
    ).read_bytes()

    def text(folder: Path) -> str:  # the reproduce line names the folder's path
        return (folder / "report.md").read_text(encoding="utf-8").replace(str(folder), "RUN")

    assert text(copy) == text(exported)


def test_a_changed_input_is_named_and_a_modified_copy_refused(
    custom: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    copy = tmp_path / "run"
    shutil.copytree(custom["run"], copy)
    changed = tmp_path / "my_envs.toml"  # the "original" environments file, edited
    changed.write_text(
        custom["envs"].read_text(encoding="utf-8") + "\n# edited\n", encoding="utf-8"
    )
    info = json.loads((copy / "run.json").read_text(encoding="utf-8"))
    info["inputs"]["environments"]["path"] = str(changed)
    (copy / "run.json").write_text(json.dumps(info), encoding="utf-8")
    run = open_run(copy)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "input changed since the run" in err[0]
    assert f"environments {changed}" in err[0] and "recorded copy" in err[0]
    assert run.environments()["clear"].visibility_m == 50.0  # the recorded copy is used
    (copy / "inputs" / "environments" / "my_envs.toml").write_text("x", encoding="utf-8")
    assert main(["export", "--run", str(copy)]) == 2
    err2 = capsys.readouterr().err.strip().splitlines()
    assert len(err2) == 1 and "was modified" in err2[0] and "my_envs.toml" in err2[0]


@pytest.mark.parametrize("layout", ["run", "job"])
def test_verify_refuses_a_recorded_copy_edited_with_the_manifest_rehashed(
    custom: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str], layout: str
) -> None:
    """A recorded copy edited and every manifest re-hashed (a forged run): ``verify``
    said OK while ``report`` and ``export`` refused it (remark of session 26). It now reads
    the recorded inputs as they do: one line naming the copy, exit 2; a job's OUT checks
    each vehicle folder below it."""
    from sensorgap.filesio import write_manifest

    out = tmp_path / "OUT"
    run = out / "system_b" if layout == "job" else out
    shutil.copytree(custom["run"], run)
    write_manifest(run)
    if layout == "job":
        write_manifest(out)
    capsys.readouterr()
    assert main(["verify", str(out)]) == 0
    said = capsys.readouterr().out
    assert "every recorded input matches run.json" in said, said
    copy = run / "inputs" / "environments" / "my_envs.toml"
    copy.write_text(copy.read_text(encoding="utf-8") + "\n# forged\n", encoding="utf-8")
    write_manifest(run)
    if layout == "job":
        write_manifest(out)
    assert main(["verify", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and str(copy) in err[0] and "was modified" in err[0], err


@pytest.mark.parametrize("beside", ["", "ranking.json", "search.sqlite"])
@pytest.mark.parametrize("text", ['{"my": "notes"}', "[1, 2]", '{"inputs": 5}', "plain"])
def test_verify_reads_only_search_runs_as_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str, beside: str
) -> None:
    """Hostile rounds 41 and 42 (F1, F5): a folder of the user's files given as ``--out``
    holding ``notes/run.json`` of their own (alone, or beside a ``ranking.json`` or a
    ``search.sqlite`` of theirs) was read by ``verify`` as a job's vehicle folder ("expected
    a JSON object"), though the command had certified it. A search run is a ``run.json``
    beside the search's store, an SQLite database."""
    user = tmp_path / "U"
    (user / "notes").mkdir(parents=True)
    (user / "notes" / "run.json").write_text(text, encoding="utf-8")
    if beside:
        (user / "notes" / beside).write_text(text, encoding="utf-8")
    assert (
        main(["nearfield", "--vehicle", "system_a", "--resolution", "0.5", "--out", str(user)]) == 0
    )
    capsys.readouterr()
    assert main(["verify", str(user)]) == 0
    said = capsys.readouterr().out
    assert "present and unchanged" in said and "recorded input" not in said, said


def test_a_refused_command_prints_one_line_not_the_changed_input_note(
    custom: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An original changed since the run gives a note ("input changed since the run");
    a command that is then refused for another reason printed the note and its error, two
    lines (remark of session 26). The note is held until the command succeeds: refused,
    one line; the same command succeeding then prints the note."""
    copy = tmp_path / "run"
    shutil.copytree(custom["run"], copy)
    changed = tmp_path / "my_envs.toml"
    changed.write_text(
        custom["envs"].read_text(encoding="utf-8") + "\n# edited\n", encoding="utf-8"
    )
    info = json.loads((copy / "run.json").read_text(encoding="utf-8"))
    info["inputs"]["environments"]["path"] = str(changed)
    (copy / "run.json").write_text(json.dumps(info), encoding="utf-8")
    r = json.loads((copy / "ranking.json").read_text(encoding="utf-8"))["ranking"][0]
    argv = _evaluate_argv(copy, r)
    capsys.readouterr()
    assert main([*argv, "--param", "no_such=1", "--out", str(tmp_path / "e1")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no_such" in err[0], err
    assert main([*argv, "--out", str(tmp_path / "e2")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "input changed since the run" in err[0], err


def test_a_run_without_recorded_inputs_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # held-out review round four: such a run was rebuilt from the shipped presets of the
    # same names (with a note), which may silently differ from what was searched
    folder = tmp_path / "old"
    folder.mkdir()
    (folder / "ranking.json").write_text(
        json.dumps(
            {
                "ranking": [
                    {"rank": 1, "scenario_id": "x", "family": "cut_in_left", "environment": "clear"}
                ],
                "settings": {"vehicle_ref": "system_a"},
            }
        ),
        encoding="utf-8",
    )
    with pytest.raises(
        InputError,
        match=r"run\.json: inputs: missing: the run does not "
        r"record its inputs",
    ):
        open_run(folder)
    assert main(["export", "--run", str(folder)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "run the search again" in err[0]
    assert sorted(p.name for p in folder.iterdir()) == ["ranking.json"]
    # without ranked rows there is nothing to rebuild: a folder of other outputs opens
    (folder / "ranking.json").unlink()
    assert open_run(folder, ranking=False).rows == []


def test_an_input_file_named_with_a_backslash(tmp_path: Path) -> None:
    """Hostile round fifteen: a family file ``back\\slash.toml`` (a legal POSIX name) was
    copied to ``inputs/families`` as is, and the manifest then listed a name its own verify,
    export and report refused. A family of that name is refused up front (its name is the
    file stem, read back from the copy); a vehicle file of such a name is recorded with
    ``_`` instead, and the run verifies and exports."""
    shipped = templates_dir() / "scenarios" / "slow_ahead_curve.toml"
    fam = tmp_path / "back\\slash.toml"
    fam.write_text(shipped.read_text(encoding="utf-8"), encoding="utf-8")
    out = tmp_path / "run"
    common = ["--environments", "snow", "--budget", "30", "--strategy", "lhs", "--out", str(out)]
    argv = ["search", "--vehicle", "system_b", "--families", str(fam), *common]
    assert main(argv) == 2 and not out.exists()
    vehicle = tmp_path / "my\\veh.toml"
    vehicle.write_text(
        (templates_dir() / "vehicles" / "system_b.toml").read_text(encoding="utf-8"),
        encoding="utf-8",
    )
    argv = ["search", "--vehicle", str(vehicle), "--families", "slow_ahead_curve", *common]
    assert main(argv) == 0
    assert (out / "inputs" / "vehicle" / "my_veh.toml").is_file()
    assert main(["verify", str(out)]) == 0
    assert main(["export", "--run", str(out)]) == 0 and main(["verify", str(out)]) == 0


def test_input_files_named_like_temporaries_are_recorded_under_other_names(
    tmp_path: Path,
) -> None:
    """Hostile round 35: an environments file ``envs.tmp`` (or a vehicle file ``v-journal``)
    was copied to ``inputs/`` under its own name, and after the whole search the run's own
    manifest refused the folder as holding a left-over temporary, leaving it half-written.
    Now such a copy is named with ``.input`` added (``run.json`` names it): the run
    verifies, exports and resumes from it."""
    envs = tmp_path / "envs.tmp"
    shutil.copyfile(templates_dir() / "environments.toml", envs)
    vehicle = tmp_path / "v-journal"
    shutil.copyfile(templates_dir() / "vehicles" / "system_b.toml", vehicle)
    out = tmp_path / "run"
    argv = ["search", "--vehicle", str(vehicle), "--environments-file", str(envs)]
    argv += ["--families", "slow_ahead_curve", "--environments", "fog_50", "--budget", "20"]
    argv += ["--strategy", "lhs", "--out", str(out)]
    assert main(argv) == 0
    inputs = json.loads((out / "run.json").read_text(encoding="utf-8"))["inputs"]
    assert inputs["environments"]["copy"] == "inputs/environments/envs.tmp.input"
    assert inputs["vehicle"]["copy"] == "inputs/vehicle/v-journal.input"
    assert _sha(out / inputs["environments"]["copy"]) == _sha(envs)
    assert main(["verify", str(out)]) == 0
    assert main([*argv, "--resume"]) == 0 and main(["verify", str(out)]) == 0
    assert main(["export", "--run", str(out)]) == 0 and main(["verify", str(out)]) == 0
