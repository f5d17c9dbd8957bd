"""``sensorgap compare`` is always complete (issue #14 item 4): what either run lacks (near
field, coverage maps, far field) is computed from that run's recorded inputs, and the
difference maps show where one vehicle detects and the other does not."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from sensorgap.cli import main
from sensorgap.config.presets import templates_dir
from sensorgap.search.compare_maps import COMPARE_GRID, DETECTS_PD
from sensorgap.search.run import run_search


@pytest.fixture(scope="module")
def cmp(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two search-only runs of System A: run ``fog`` with an environments file redefining
    ``clear`` as 50 m fog, run ``std`` with the shipped presets; compared."""
    root = tmp_path_factory.mktemp("cmpmaps")
    text = (templates_dir() / "environments.toml").read_text(encoding="utf-8")
    head, tail = text.split("[environments.clear]", 1)
    tail = tail.replace("visibility_m = 23000.0", "visibility_m = 50.0", 1)
    envs = root / "my_envs.toml"
    envs.write_text(head + "[environments.clear]" + tail, encoding="utf-8")
    assert (
        main(
            [
                "search",
                "--vehicle",
                "system_a",
                "--families",
                "crossing_pedestrian",
                "--environments",
                "clear",
                "--environments-file",
                str(envs),
                "--budget",
                "30",
                "--strategy",
                "lhs",
                "--out",
                str(root / "fog"),
            ]
        )
        == 0
    )
    run_search(
        "system_a",
        ["crossing_pedestrian"],
        ["clear"],
        30,
        1,
        3,
        root / "std",
        strategy="lhs",
        progress=False,
    )
    assert main(["compare", str(root / "fog"), str(root / "std"), "--out", str(root / "cmp")]) == 0
    return root


def test_complete_without_not_run(cmp: Path) -> None:
    out = cmp / "cmp"
    md = (out / "report.md").read_text(encoding="utf-8")
    assert "Not part of this run" not in md
    assert "Not part of this run" not in (out / "report.html").read_text(encoding="utf-8")
    # what each run lacked was computed for the comparison, and said so
    for tag in ("a", "b"):
        made = out / f"{tag}_system_a"
        assert (made / "nearfield" / "nearfield.json").is_file()
        assert (made / "coverage" / "car_clear" / "coverage.npz").is_file()
        assert (made / "farfield" / "clear" / "farfield.csv").is_file()
    assert (
        md.count(
            "computed for this comparison from the run's recorded inputs "
            "(vehicle, environments, target classes): near field, coverage "
            "car_clear, far field clear"
        )
        == 2
    )
    # the input run folders were not written to
    for run in ("fog", "std"):
        assert not (cmp / run / "nearfield").exists() and not (cmp / run / "coverage").exists()
    # the difference map is listed and linked
    assert "## Coverage maps side by side and their difference" in md
    assert "(difference/car_clear/difference.png)" in md
    assert (out / "difference" / "car_clear" / "difference.png").read_bytes()[:4] == b"\x89PNG"
    assert "(farfield_pd_vs_distance.png)" in md
    assert json.loads((out / "manifest.json").read_text())


def test_difference_map_uses_each_runs_recorded_environment(cmp: Path) -> None:
    out = cmp / "cmp"
    with np.load(out / "difference" / "car_clear" / "difference.npz") as z:
        pa, pb, diff = z["pd_a"], z["pd_b"], z["difference"]
        x, y = z["x"], z["y"]
    with np.load(out / "a_system_a" / "coverage" / "car_clear" / "coverage.npz") as z:
        assert np.array_equal(z["pd"], pa)
    with np.load(out / "b_system_a" / "coverage" / "car_clear" / "coverage.npz") as z:
        assert np.array_equal(z["pd"], pb)
    assert np.array_equal(diff, pa - pb)
    xmin, xmax, ymin, ymax, res = COMPARE_GRID
    assert x[0] == xmin + res / 2 and x[-1] == xmax - res / 2 and len(y) == (ymax - ymin) / res
    # the same vehicle: run A's "clear" is its recorded 50 m fog, so A never detects where
    # B (shipped clear air) does not, and B detects far more
    s = json.loads((out / "difference" / "car_clear" / "summary.json").read_text())
    assert s["detects_pd"] == DETECTS_PD
    assert s["area_m2"]["only_a_m2"] == 0.0 and s["area_m2"]["only_b_m2"] > 1000.0
    assert s["area_m2"]["only_b_m2"] == np.count_nonzero((pb >= 0.5) & (pa < 0.5)) * res**2
    md = (out / "report.md").read_text(encoding="utf-8")
    assert "environment 'clear' is defined differently by the two runs" in md
    # the far field, too: A (fog) sees less far along the lane than B (clear air)
    fa = json.loads((out / "a_system_a" / "farfield" / "clear" / "summary.json").read_text())
    fb = json.loads((out / "b_system_a" / "farfield" / "clear" / "summary.json").read_text())
    assert fa["levels_m"]["pd>=0.5"] < fb["levels_m"]["pd>=0.5"]


def test_compare_grid_is_the_default_jobs() -> None:
    from sensorgap.jobs import COVERAGE_HEADING_DEG, DEFAULT_GRID
    from sensorgap.search.compare_maps import COMPARE_HEADING_DEG

    assert COMPARE_GRID == DEFAULT_GRID and COMPARE_HEADING_DEG == COVERAGE_HEADING_DEG


def test_unreadable_coverage_map_is_one_line_exit_2(
    cmp: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    import shutil

    run = tmp_path / "run"
    shutil.copytree(cmp / "std", run)
    bad = run / "coverage" / "car_clear"
    bad.mkdir(parents=True)
    (bad / "summary.json").write_text(
        json.dumps({"vehicle": "System A", "environment": "clear", "target": "car"})
    )
    (bad / "coverage.npz").write_bytes(b"PK\x03\x04 not a zip")
    out = tmp_path / "cmp"
    assert main(["compare", str(cmp / "fog"), str(run), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "coverage.npz" in err[0] and "unreadable coverage map" in err[0]
    assert not out.exists()  # nothing was computed or left behind


@pytest.mark.parametrize(
    ("name", "part"),
    [
        ("System B", "system_b"),
        ("B.tmp", "b.tmp_"),  # hostile round 36: compare's folder b_b.tmp/ was refused
        ("X-WAL", "x-wal_"),  # a journal's name only once lower-cased
        (".hidden.tmp", "hidden.tmp_"),
        ("a-shm", "a-shm_"),
        ("  ", "vehicle"),
    ],
)
def test_a_vehicle_name_never_makes_a_folder_verify_would_refuse(name: str, part: str) -> None:
    """``slug`` turns a vehicle's name into compare's folder names (``b_<slug>/``); a name
    that would read like a temporary or journal file gets ``_`` added, a leading dot goes:
    such a folder was written whole, then the comparison's own manifest refused it."""
    from sensorgap.filesio import is_temporary
    from sensorgap.search.compare_maps import slug

    assert slug(name) == part
    assert not is_temporary(f"b_{slug(name)}") and not slug(name).startswith(".")
