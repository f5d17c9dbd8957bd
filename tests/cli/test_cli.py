"""The command line end to end (in process and as a subprocess): outputs, exit codes,
one-line errors, determinism."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from sensorgap.cli import main


def run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "sensorgap.cli", *args], capture_output=True, text=True, timeout=300
    )


def test_probe_columns_and_values(tmp_path: Path) -> None:
    pts = tmp_path / "p.csv"
    pts.write_text("x,y\n10,0\n50,3\n-20,-2\n")
    out = tmp_path / "o.csv"
    assert (
        main(
            [
                "probe",
                "--vehicle",
                "system_a",
                "--environment",
                "clear",
                "--target",
                "car",
                "--points",
                str(pts),
                "--out",
                str(out),
            ]
        )
        == 0
    )
    rows = list(csv.reader(out.read_text().splitlines()))
    header = rows[0]
    assert header[:3] == ["x", "y", "z"] and header[-1] == "pd"
    assert "radar_front_center.snr_db" in header and "radar_front_center.pd" in header
    assert len(header) == 3 + 2 * 23 + 1
    z = [float(r[2]) for r in rows[1:]]
    assert z == [0.75, 0.75, 0.75]  # the car's reference height
    pd = [float(r[-1]) for r in rows[1:]]
    assert all(0.0 <= p <= 1.0 for p in pd) and pd[0] == 1.0


def test_coverage_outputs_and_determinism(tmp_path: Path) -> None:
    args = [
        "coverage",
        "--vehicle",
        "system_b",
        "--environment",
        "glare_front_right",
        "--target",
        "car",
        "--resolution",
        "1",
        "--extent",
        "-20,100,-20,20",
    ]
    assert main([*args, "--out", str(tmp_path / "a")]) == 0
    assert main([*args, "--out", str(tmp_path / "b")]) == 0
    for name in ("coverage.npz", "coverage.png", "summary.json"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    data = np.load(tmp_path / "a" / "coverage.npz")
    assert data["pd"].shape == (40, 120)
    assert np.all((data["pd"] >= 0) & (data["pd"] <= 1))
    summary = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert summary["environment"] == "glare_front_right"
    assert any(": glare:" in e for e in summary["effects"])
    assert summary["area_m2_by_level"]["pd>0"] > 0


def test_schema_prints_json_schema(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["schema"]) == 0
    schemas = json.loads(capsys.readouterr().out)
    assert set(schemas) == {"vehicle", "environments", "targets"}
    variants = schemas["vehicle"]["$defs"]["DeviceConfig"]["oneOf"]
    assert {v["properties"]["type"]["const"] for v in variants} == {
        "camera",
        "lidar",
        "radar",
        "ultrasonic",
    }


def test_bad_vehicle_file_via_cli(tmp_path: Path) -> None:
    """The one subprocess smoke test of bad input (the bad-input corpus runs in process:
    tests/bad_inputs/cases.toml holds the former per-case subprocess tests of this file)."""
    bad = tmp_path / "v.toml"
    bad.write_text("schema_version = 1\n[vehicle]\nname = 'x'\n")
    proc = run(
        "probe",
        "--vehicle",
        str(bad),
        "--environment",
        "clear",
        "--target",
        "car",
        "--points",
        str(bad),
    )
    assert proc.returncode == 2
    # every missing field listed, one line each, no traceback
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 7 and "Traceback" not in proc.stderr
    assert all(ln.startswith(f"sensorgap: error: {bad}: ") for ln in lines)
    assert any("sensors: Field required" in ln for ln in lines)


def test_run_folders_carry_a_manifest(tmp_path: Path) -> None:
    import hashlib

    out = tmp_path / "cov"
    assert (
        main(
            [
                "coverage",
                "--vehicle",
                "system_a",
                "--environment",
                "clear",
                "--target",
                "car",
                "--resolution",
                "2",
                "--extent=-10,40,-10,10",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    manifest = json.loads((out / "manifest.json").read_text())
    files = manifest["files"]
    assert set(files) == {"coverage.npz", "coverage.png", "summary.json"}
    for name, entry in files.items():
        data = (out / name).read_bytes()
        assert entry == {"bytes": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def test_library_errors_name_arguments_and_the_cli_names_flags(
    capsys: pytest.CaptureFixture[str],
) -> None:
    # issue #16: a script calling the library is told about the argument
    # (``load_target("horse")`` -> "target: ..."), the CLI user about the option
    from sensorgap.config import load_target
    from sensorgap.errors import InputError

    with pytest.raises(InputError) as info:
        load_target("horse")
    assert info.value.line().startswith("target: unknown target 'horse'")
    assert (
        main(
            [
                "search",
                "--vehicle",
                "system_b",
                "--families",
                "cut_in_right",
                "--environments",
                "clear",
                "--budget",
                "0",
                "--out",
                "unused",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "sensorgap: error: --budget: must be within" in err


def test_vehicle_name_with_mathtext_is_drawn_as_written(tmp_path: Path) -> None:
    # held-out review (#18): a name like "A $x^{$" was parsed as matplotlib math in the
    # figure titles (internal error); names are drawn as written
    from sensorgap.config.presets import templates_dir

    text = (templates_dir() / "vehicles" / "system_a.toml").read_text()
    v = tmp_path / "v.toml"
    v.write_text(text.replace('name = "System A"', 'name = "A $x^{$"', 1))
    assert (
        main(
            [
                "coverage",
                "--vehicle",
                str(v),
                "--environment",
                "clear",
                "--target",
                "car",
                "--resolution",
                "1",
                "--extent",
                "0,10,0,10",
                "--out",
                str(tmp_path / "c"),
            ]
        )
        == 0
    )
    assert (
        main(
            ["nearfield", "--vehicle", str(v), "--out", str(tmp_path / "n"), "--resolution", "0.25"]
        )
        == 0
    )
    assert (tmp_path / "c" / "coverage.png").is_file()
