"""Export test fixtures: a small search run, its catalogs in both styles, a run with one
scenario of every family (all family kinds), and esmini when it is installed."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from sensorgap.cli import main
from sensorgap.export.simulate import find_esmini
from sensorgap.models import load_system
from sensorgap.scenarios import load_family
from sensorgap.scenarios.trajectory import InfeasibleScenario
from sensorgap.search.run import run_search
from sensorgap.search.runfolder import record_inputs, write_search_record

FAMILIES = [
    "cut_in_left",
    "overtake_left",
    "slow_ahead_curve",
    "crossing_pedestrian",
    "crossing_cyclist",
]
ENVS = ["clear", "glare_front_right", "fog_50", "rain_25", "snow"]
#: Every shipped family: together they use every built-in family kind.
ALL_FAMILIES = [
    "cut_in_left",
    "cut_in_right",
    "overtake_left",
    "slow_ahead_curve",
    "stopped_rural_curve",
    "crossing_pedestrian",
    "crossing_cyclist",
    "pedestrian_behind_parked_cars",
    "cut_out_reveal",
    "cut_in_behind_truck",
]


def _esmini() -> Path | None:
    try:
        return find_esmini(None)
    except Exception:  # noqa: BLE001 - absent: the esmini tests skip
        return None


ESMINI = _esmini()
needs_esmini = pytest.mark.skipif(
    ESMINI is None,
    reason="esmini is not installed (set SENSORGAP_ESMINI or put esmini on "
    "PATH); it is not on any package registry, CI has none",
)


def _reached(params: dict[str, object], duration_s: float) -> bool:
    """Whether a slower car ahead is reached in the first 60 % of the encounter (the gap
    closes at the speed difference): the esmini tests brake behind it and need the rest
    to settle at its speed."""
    closing = float(params["ego_speed_m_s"]) - float(params["target_speed_m_s"])  # type: ignore[arg-type]
    return closing * 0.6 * duration_s > float(params["gap0_m"])  # type: ignore[arg-type]


def write_family_run(out: Path, per_family: int = 1, seed: int = 7) -> Path:
    """A run folder (``ranking.json``) with ``per_family`` feasible scenarios of every
    shipped family: parameters drawn uniformly (seeded) from each family's space and kept
    when the family's generator accepts them (and a slower car ahead is reached within
    the encounter), environment ``clear``. Not a search result:
    it exercises every family kind of the exporter."""
    rng = np.random.default_rng(seed)
    rows: list[dict[str, object]] = []
    for name in ALL_FAMILIES:
        fam = load_family(name)
        found = 0
        while found < per_family:
            params = fam.decode(rng.random(len(fam.space)))
            try:
                fam.generate(params)
            except InfeasibleScenario:  # includes OffRoad
                continue
            if fam.kind.name == "slow_ahead" and not _reached(params, fam.duration_s):
                continue
            found += 1
            sid = hashlib.sha256(f"{name}/{found}/{params}".encode()).hexdigest()[:12]
            rows.append(
                {
                    "rank": len(rows) + 1,
                    "scenario_id": sid,
                    "family": name,
                    "environment": "clear",
                    **{f"p_{k}": v for k, v in params.items()},
                }
            )
    out.mkdir(parents=True, exist_ok=True)
    (out / "ranking.json").write_text(
        json.dumps({"ranking": rows, "settings": {"vehicle_ref": "system_a"}}), encoding="utf-8"
    )
    # its inputs recorded as a search records them (a run without them is refused)
    system = load_system("system_a")
    write_search_record(
        out,
        "system_a",
        {},
        record_inputs(
            out,
            Path(system.source),
            None,
            system.config.reaction,
            [load_family(n) for n in ALL_FAMILIES],
        ),
    )
    return out


@pytest.fixture(scope="session")
def run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small search run (system_b, five families, five environments, top 6)."""
    out = tmp_path_factory.mktemp("run")
    run_search("system_b", FAMILIES, ENVS, 500, 2, 6, out, strategy="lhs", progress=False)
    return out


@pytest.fixture(scope="session")
def catalog(run_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The replay-style catalog (timed polylines) of the small run."""
    out = tmp_path_factory.mktemp("catalog")
    assert main(["export", "--run", str(run_dir), "--out", str(out), "--style", "replay"]) == 0
    return out


@pytest.fixture(scope="session")
def maneuver_catalog(run_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The maneuver-style catalog (the default style) of the small run."""
    out = tmp_path_factory.mktemp("maneuver")
    assert main(["export", "--run", str(run_dir), "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="session")
def encounter_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A small search run whose ranked scenarios start their manoeuvres on relative
    triggers (system_a; lane changes, mostly the default job's cut-out reveal)."""
    out = tmp_path_factory.mktemp("encounter_run")
    run_search(
        "system_a",
        ["cut_out_reveal", "cut_in_behind_truck", "cut_in_left", "overtake_left"],
        ["fog_50", "snow"],
        400,
        3,
        6,
        out,
        strategy="lhs",
        progress=False,
    )
    return out


@pytest.fixture(scope="session")
def family_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One scenario of every shipped family (see ``write_family_run``)."""
    return write_family_run(tmp_path_factory.mktemp("families"))


#: OpenSCENARIO versions and export styles the catalogs are written in.
VERSIONS = ("1.0", "1.1", "1.2", "1.3")
STYLES = ("maneuver", "replay")


@pytest.fixture(scope="session")
def family_catalogs(
    family_run: Path, tmp_path_factory: pytest.TempPathFactory
) -> dict[tuple[str, str], Path]:
    """The catalog of ``family_run`` (every family kind) in every style and version:
    (style, version) -> folder (no coverage maps)."""
    from sensorgap.export import export_catalog

    out = {}
    for style in STYLES:
        for version in VERSIONS:
            folder = tmp_path_factory.mktemp(f"family_{style}_{version.replace('.', '')}")
            export_catalog(family_run, folder, osc_version=version, coverage=False, style=style)
            out[(style, version)] = folder
    return out
