"""Runs the bad-input corpus (tests/bad_inputs/cases.toml, format in its README): every
case gives its one-line message on stderr and exit 2, no traceback, nothing half-written.
Also: an internal error is exit 1 and says so, with a traceback only under --debug."""

from __future__ import annotations

import hashlib
import json
import os
import re
import resource
import shutil
import sqlite3
import subprocess
import sys
import tomllib
from pathlib import Path
from typing import Any

import pytest

import sensorgap
from sensorgap.cli import main

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
CASES: list[dict[str, Any]] = tomllib.loads(
    (HERE / "bad_inputs" / "cases.toml").read_text(encoding="utf-8")
)["case"]
SRC = str(Path(sensorgap.__file__).resolve().parents[1])


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
    out = tmp_path_factory.mktemp("run") / "run"
    # System B on a rural curve into the low sun: a sensor-critical scenario to export
    assert (
        main(
            [
                "search",
                "--vehicle",
                "system_b",
                "--families",
                "stopped_rural_curve",
                "--environments",
                "glare_front_right",
                "--budget",
                "60",
                "--top",
                "2",
                "--strategy",
                "lhs",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    assert (
        main(
            [
                "nearfield",
                "--vehicle",
                "system_a",
                "--resolution",
                "0.2",
                "--out",
                str(out / "nearfield"),
            ]
        )
        == 0
    )
    assert main(["export", "--run", str(out)]) == 0
    return out


def _write_files(case: dict[str, Any], folder: Path, key: str = "files") -> None:
    for name, spec in case.get(key, {}).items():
        if isinstance(spec, str):
            text = spec
        else:
            text = (REPO / spec["from"]).read_text(encoding="utf-8")
            for old, new in spec.get("replace", []):
                assert old in text, f"{case['name']}: {old!r} not in {spec['from']}"
                text = text.replace(old, new)
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_text(text, encoding="utf-8")


def _edit_manifest(run: Path, entry: str) -> None:
    manifest = json.loads((run / "manifest.json").read_text())
    manifest["files"][entry] = {"bytes": 4, "sha256": "0" * 64}
    (run / "manifest.json").write_text(json.dumps(manifest))


def _edit_run(case: dict[str, Any], run: Path) -> None:
    """``run_files`` (inline text written into ``{run}``), ``run_edit`` ([file, regex,
    replacement]: the first match replaced) and ``run_input_edit`` (a recorded input's
    copy edited, [old, new] pairs, with its SHA-256 in run.json updated to match)."""
    for name, text in case.get("run_files", {}).items():
        (run / name).write_text(text, encoding="utf-8")
    for name, pattern, repl in case.get("run_edit", []):
        text, n = re.subn(pattern, repl, (run / name).read_text(encoding="utf-8"), count=1)
        assert n == 1, f"{case['name']}: {pattern!r} not in {name}"
        (run / name).write_text(text, encoding="utf-8")
    for label, pairs in case.get("run_input_edit", {}).items():
        info = json.loads((run / "run.json").read_text())
        copy = run / info["inputs"][label]["copy"]
        text = copy.read_text(encoding="utf-8")
        for old, new in pairs:
            assert old in text, f"{case['name']}: {old!r} not in {copy.name}"
            text = text.replace(old, new)
        copy.write_text(text, encoding="utf-8")
        info["inputs"][label]["sha256"] = hashlib.sha256(copy.read_bytes()).hexdigest()
        (run / "run.json").write_text(json.dumps(info))


def _sql(db: Path, script: str) -> None:
    con = sqlite3.connect(db)
    con.executescript(script)
    con.close()


def _many_geometries(path: Path, n: int) -> None:
    geoms = "".join(
        f'<geometry s="{i}" x="{i}" y="0" hdg="0" length="1"><line/></geometry>' for i in range(n)
    )
    lanes = (
        '<lanes><laneSection s="0"><center><lane id="0" type="none"/></center><right>'
        '<lane id="-1" type="driving"><width sOffset="0" a="3.5" b="0" c="0" d="0"/>'
        "</lane></right></laneSection></lanes>"
    )
    path.write_text(
        f'<?xml version="1.0"?><OpenDRIVE><header revMajor="1" revMinor="6"/>'
        f'<road id="1" junction="-1" length="{n}"><planView>{geoms}</planView>'
        f"{lanes}</road></OpenDRIVE>"
    )


def _coverage_map(folder: Path, damage: str) -> None:
    """A small coverage map (coverage.npz, summary.json) in ``folder`` with one damage:
    ``pd_nan``, ``x_reversed``, ``huge_header`` (pd's .npy header claims 1e10 cells),
    ``summary_nan`` (an area of summary.json is NaN)."""
    import io
    import zipfile

    import numpy as np

    folder.mkdir(parents=True)
    x, y = np.arange(-59.0, 160.0, 2.0), np.arange(-39.0, 40.0, 2.0)
    arrays = {
        "x": x,
        "y": y,
        "pd": np.zeros((y.size, x.size)),
        "resolution": np.array(2.0),
        "height": np.array(0.75),
    }
    if damage == "pd_nan":
        arrays["pd"][0, 0] = np.nan
    if damage == "x_reversed":
        arrays["x"] = x[::-1].copy()
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as zf:
        for k, v in arrays.items():
            b = io.BytesIO()
            np.save(b, v)
            data = b.getvalue()
            if damage == "huge_header" and k == "pd":
                hdr = "{'descr': '<f8', 'fortran_order': False, 'shape': (100000, 100000), }"
                hdr = hdr.ljust(117) + "\n"
                data = b"\x93NUMPY\x01\x00" + len(hdr).to_bytes(2, "little") + hdr.encode()
            zf.writestr(f"{k}.npy", data)
    (folder / "coverage.npz").write_bytes(buf.getvalue())
    area = "NaN" if damage == "summary_nan" else "0.0"
    summary = (
        '{"area_m2_by_level": {"pd=1.0": AREA, "pd>=0.8": 0.0, "pd>=0.5": 0.0, "pd>0": 0.0, '
        '"pd=0": 17600.0}, "environment": "clear", "grid": {"resolution_m": 2.0}, '
        '"target": "car"}'
    )
    (folder / "summary.json").write_text(summary.replace("AREA", area))


def _setup(case: dict[str, Any], argv: list[str], folder: Path, out: Path, run: Path) -> None:
    db = out / "search.sqlite"
    for step in case.get("setup", []):
        if step == "out_parent_is_file":
            out.write_text("a file where a folder is expected")
        elif step == "sparse_huge_road":
            with (folder / "huge.xodr").open("wb") as f:
                f.truncate(300 * 2**20)  # sparse: costs no disk
        elif step == "delete_first_scenario":
            next((run / "scenarios").glob("*.xosc")).unlink()
        elif step == "corrupt_nearfield":
            (run / "nearfield" / "nearfield.json").write_text("{broken")
        elif step == "existing_search":
            assert main([*argv[:-2], "--out", str(out)]) == 0
            _write_files(case, folder, "files_after")
        elif step == "store_garbage":
            db.write_bytes(b"definitely not an SQLite database " * 200)
        elif step == "store_truncated":
            db.write_bytes(db.read_bytes()[:1500])
        elif step == "store_wrong_schema":
            _sql(db, "DROP TABLE candidates; CREATE TABLE candidates (x TEXT);")
        elif step == "store_bad_json":
            _sql(db, "UPDATE candidates SET params = '{not json' WHERE idx = 0;")
        elif step == "store_param_changed":  # a parameter of row 0 edited, its id kept
            _sql(db, "UPDATE candidates SET params = json_set(params, '$.zz_m', 1) WHERE idx = 0;")
        elif step == "store_not_a_probability":
            _sql(
                db,
                "UPDATE candidates SET metrics = replace(metrics, "
                "'\"mean_pd\": ', '\"mean_pd\": 7') WHERE idx = 0;",
            )
        elif step == "store_feasible_text":
            _sql(db, "UPDATE candidates SET feasible = 'yes' WHERE idx = 0;")
        elif step == "store_empty_metrics":
            _sql(db, "UPDATE candidates SET metrics = '{}' WHERE idx = 0;")
        elif step == "store_deep_json":
            _sql(
                db,
                "UPDATE candidates SET params = '" + "[" * 5000 + "]" * 5000 + "' WHERE idx = 0;",
            )
        elif step.startswith("deep_json:"):  # deep_json:<file in {dir}>
            (folder / step.removeprefix("deep_json:")).parent.mkdir(parents=True, exist_ok=True)
            (folder / step.removeprefix("deep_json:")).write_text("[" * 5000 + "]" * 5000)
        elif step == "huge_vehicle_name":  # a 1 MB name in {dir}/v.toml
            v = folder / "v.toml"
            v.write_text(
                re.sub(r'(?m)^name = ".*"$', 'name = "' + "A" * 2**20 + '"', v.read_text(), count=1)
            )
        elif step == "road_symlink_loop":
            (folder / "loop.xodr").symlink_to(folder / "loop.xodr")
        elif step in ("deep_catalog_json", "deep_ranking_json"):
            name = "catalog.json" if step == "deep_catalog_json" else "ranking.json"
            (run / name).write_text('{"junk": ' + "[" * 5000 + "]" * 5000 + "}")
        elif step == "out_roads_symlink":  # {out}/roads links to {dir}/elsewhere
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the export's")
            out.mkdir()
            (out / "roads").symlink_to(folder / "elsewhere")
        elif step == "run_roads_symlink":  # {run}/roads links to {dir}/elsewhere
            (folder / "elsewhere").mkdir()
            (folder / "elsewhere" / "keep.xodr").write_text("not the export's")
            shutil.rmtree(run / "roads")
            (run / "roads").symlink_to(folder / "elsewhere")
        elif step == "many_geometries":
            _many_geometries(folder / "many.xodr", 50_001)
            argv[argv.index(str(folder / "r.xodr"))] = str(folder / "many.xodr")
        elif step == "big_csv_field":
            (folder / "p.csv").write_text("x,y\n1," + "1" * 200_000 + "\n")
        elif step == "manifest_escape":
            _edit_manifest(run, "../../etc/passwd")
        elif step == "manifest_absolute":
            _edit_manifest(run, "/etc/passwd")
        elif step == "symlink_out":
            (run / "etc_link").symlink_to("/etc")
        elif step == "symlink_loop":
            (run / "loop").symlink_to(run / "loop")
        elif step == "journal_file":
            (run / "search.sqlite-journal").write_bytes(b"journal")
        elif step == "hidden_tmp":
            (run / ".x.tmp.xosc").write_text("<half")
        elif step == "edit_first_scenario":
            first = sorted((run / "scenarios").glob("*.xosc"))[0]
            first.write_text(first.read_text() + "<!-- edited -->\n")
        elif step == "unlisted_file":
            (run / "extra.txt").write_text("not listed")
        elif step == "many_ranking_rows":  # row 0 of {run}/ranking.json, 301 times
            data = json.loads((run / "ranking.json").read_text())
            row = data["ranking"][0]
            data["ranking"] = [{**row, "rank": i + 1} for i in range(301)]
            (run / "ranking.json").write_text(json.dumps(data))
        elif step == "duplicate_first_row":  # row 0 of {run}/ranking.json twice
            data = json.loads((run / "ranking.json").read_text())
            data["ranking"].append({**data["ranking"][0], "rank": len(data["ranking"]) + 1})
            (run / "ranking.json").write_text(json.dumps(data))
        elif step.startswith("coverage_map:"):  # {run}/coverage/car_clear, damaged
            _coverage_map(run / "coverage" / "car_clear", step.removeprefix("coverage_map:"))
        elif step == "manifest_symlink":
            (folder / "manifest.json").symlink_to("/etc/hostname")
        else:
            raise AssertionError(f"unknown setup step {step!r}")


def _files(folder: Path) -> set[str]:
    return (
        {p.relative_to(folder).as_posix() for p in folder.rglob("*") if p.is_file()}
        if folder.is_dir()
        else set()
    )


@pytest.mark.parametrize("case", CASES, ids=[c["name"] for c in CASES])
def test_bad_input(
    case: dict[str, Any], tmp_path: Path, finished_run: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "case"
    folder.mkdir()
    out = tmp_path / "out"
    run = tmp_path / "run"
    if any("{run}" in a for a in case["argv"]):
        shutil.copytree(finished_run, run)
    _write_files(case, folder)
    if run.is_dir():
        _edit_run(case, run)
        if case.get("drop_manifest"):  # test a file's own check, not the folder's integrity
            (run / "manifest.json").unlink()
    subs = {
        "{dir}": str(folder),
        "{out}": str(out),
        "{run}": str(run),
        "{templates}": str(REPO / "templates"),
        "{roads}": str(REPO / "roads"),
    }
    argv = [a for a in case["argv"]]
    for i, a in enumerate(argv):
        for k, v in subs.items():
            a = a.replace(k, v)
        argv[i] = a
    _setup(case, argv, folder, out, run)
    before = _files(out)
    if "rlimit_fsize" in case:
        limit = int(case["rlimit_fsize"])

        def cap() -> None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

        proc = subprocess.run(
            [sys.executable, "-m", "sensorgap", *argv],
            capture_output=True,
            env={**os.environ, "PYTHONPATH": SRC},
            preexec_fn=cap,
            timeout=300,
            check=False,
        )
        code, err = proc.returncode, proc.stderr.decode("utf-8", "replace")
    else:
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse errors
            code = int(exc.code or 0)
        err = capsys.readouterr().err
    # a run folder's one-line notes and warnings (docs/runs.md) are not errors
    lines = [
        ln
        for ln in err.strip().splitlines()
        if not ln.startswith(("sensorgap: note: ", "sensorgap: warning: "))
    ]
    assert code == case["exit"], f"exit {code}: {err}"
    # one line per error found (every validation error is listed): as many as the case
    # says, else at least one
    if "lines" in case:
        assert len(lines) == int(case["lines"]), err
    assert lines, err
    assert all(ln.startswith("sensorgap") and ": error: " in ln for ln in lines), err
    assert "Traceback" not in err
    assert re.search(case["message"], lines[0]), lines[0]
    after = _files(out)
    assert not [f for f in after if ".tmp" in f], after
    if code == 2:
        assert after <= before, f"files written despite the error: {sorted(after - before)}"
    if (folder / "elsewhere").is_dir():  # a symlinked output folder: nothing changed there
        assert _files(folder / "elsewhere") == {"keep.xodr"}


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
