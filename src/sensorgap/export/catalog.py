"""The test catalog of a vehicle: one OpenSCENARIO file per ranked scenario plus its road,
in the ``maneuver`` style (default; ``export.maneuver``) or the ``replay`` style
(``export.xosc``).

Layout of ``DIR`` (a search run folder, or ``--out``):

* ``scenarios/<scenario_id>.xosc`` referencing ``../roads/<road>.xodr``;
* ``roads/*.xodr`` (copies of the roads the scenarios run on);
* ``coverage/<target>_<environment>.npz|.png``: the fused Pd maps (no sun) the search's
  lookup used for each (environment, target) of the catalog;
* ``ranking.csv``, ``ranking.json`` (copied when ``--out`` is another folder);
* ``catalog.json``: the index: every file with its role, size and SHA-256, each scenario
  with its rank, family, environment, target, risk, road and the validation results;
* ``manifest.json``.

Every file is validated against the official XSD of its version and by our semantic checks
before the index is written; a failure is an error, not a warning.
"""

from __future__ import annotations

import shutil
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.atomic import atomic_path, atomic_write_bytes
from sensorgap.coverage import GridSpec, Scene, evaluate_grid
from sensorgap.coverage.figurememo import drawn_system, save_drawn
from sensorgap.coverage.plot import coverage_figure
from sensorgap.errors import InputError
from sensorgap.export.maneuver import build_maneuver_scenario, supported
from sensorgap.export.spec import ScenarioSpec, read_run, specs_of_run
from sensorgap.export.validate import FOOTWAY_M, semantic_errors, xsd_errors
from sensorgap.export.xosc import DEFAULT_VERSION, VERSIONS, build_scenario, write_scenario_xml
from sensorgap.filesio import (
    refuse_certified_by_other,
    refuse_if_changed,
    refuse_if_source_changed,
    write_json,
    write_manifest,
    write_npz,
)
from sensorgap.models import Conditions
from sensorgap.provenance import sha256_of
from sensorgap.roads import read_opendrive
from sensorgap.search.runfolder import INPUTS_DIR, copy_record

#: Export styles: ``maneuver`` (actions started relative to the ego, for a system under
#: test; default) and ``replay`` (the evaluated 20 Hz states as timed polylines).
STYLES = ("maneuver", "replay")
DEFAULT_STYLE = "maneuver"
#: Grid of the coverage maps written into the catalog (vehicle frame, m).
CATALOG_GRID = (-120.0, 260.0, -40.0, 40.0, 0.5)


class ExportError(RuntimeError):
    """An exported file failed validation (a bug, never bad input)."""


def _lanes(spec: ScenarioSpec) -> dict[str, list[int]]:
    st = spec.family.settings
    lanes = [int(st[k]) for k in ("ego_lane", "target_lane", "occluder_lane", "lane") if k in st]
    return {str(st["road_id"]): lanes}


def write_xosc(
    spec: ScenarioSpec, path: Path, road_rel: str, version: str, style: str = DEFAULT_STYLE
) -> None:
    """One scenario's OpenSCENARIO file (atomically) in ``style``, its road referenced as
    ``road_rel`` (relative to the file)."""
    sc = (
        build_scenario(spec, road_rel, version)
        if style == "replay"
        else build_maneuver_scenario(spec, road_rel, version)[0]
    )
    with atomic_path(path) as tmp:
        write_scenario_xml(sc, tmp)


def _coverage_maps(specs: list[ScenarioSpec], out: Path) -> list[Path]:
    written = []
    xmin, xmax, ymin, ymax, res = CATALOG_GRID
    done = set()
    for sp in specs:
        key = (sp.environment_name, sp.target.name)
        if key in done:
            continue
        done.add(key)
        env = sp.environment.model_copy(update={"sun": None})
        target = sp.target  # the run's recorded class, as its scenarios
        grid = GridSpec(xmin, xmax, ymin, ymax, res, target.reference_height_m)
        cov = evaluate_grid(
            Scene(sp.system, target, Conditions(env=env, sun_direction=None)), grid, workers=2
        )
        stem = f"{target.name}_{sp.environment_name}"
        write_npz(
            out / f"{stem}.npz",
            {"pd": cov.fused.astype(np.float32), "xs": grid.xs(), "ys": grid.ys()},
        )
        title = (
            f"{sp.system.name}: {target.name}, "
            f"{sp.environment_name} (no sun), Pd used by the search lookup"
        )
        save_drawn(
            ("coverage_figure", cov.fused, grid, drawn_system(sp.system), title),
            partial(coverage_figure, cov, sp.system, title),
            out / f"{stem}.png",
            dpi=80,
        )
        written += [out / f"{stem}.npz", out / f"{stem}.png"]
    return written


def refuse_linked_paths(out: Path) -> None:
    """Refuse a folder the export writes into (or deletes stale files from) that is a
    symbolic link: it would write outside ``out``."""
    subs = [out / s for s in ("scenarios", "roads", "coverage", INPUTS_DIR)]
    if (out / INPUTS_DIR).is_dir() and not (out / INPUTS_DIR).is_symlink():
        subs += sorted((out / INPUTS_DIR).iterdir())
    # the files it renames onto (refused by atomic_path only after the scenarios were
    # rewritten: a half-updated catalog)
    subs += [
        out / f
        for f in ("catalog.json", "ranking.json", "ranking.csv", "run.json", "manifest.json")
    ]
    for p in subs:
        if p.is_symlink():
            raise InputError(
                p,
                "",
                "is a symbolic link; export writes only inside the "
                "catalog folder (remove the link or choose another --out)",
            )


#: Files only a search run folder holds (never a catalog exported elsewhere).
SEARCH_RUN_FILES = ("search.sqlite", "summary.json", "unavoidable.csv")
#: What an export writes into its folder (``filesio.refuse_if_changed``): everything else
#: listed in an existing manifest must be unchanged before the manifest is rewritten.
EXPORT_WRITES = ("scenarios/", "roads/", "coverage/*", "catalog.json", "simulation.csv")
#: What an export into another folder copies from the run (``filesio.refuse_if_source_changed``).
COPIED_FROM_RUN = ("ranking.csv", "ranking.json", "run.json", f"{INPUTS_DIR}/")


def export_catalog(
    run_dir: Path,
    out_dir: Path | None = None,
    osc_version: str = DEFAULT_VERSION,
    top: int | None = None,
    coverage: bool = True,
    style: str = DEFAULT_STYLE,
) -> dict[str, Any]:
    """Write the catalog of a search run in ``style`` (see the module docstring); returns
    the index."""
    if style not in STYLES:
        raise InputError("style", "", f"must be one of {', '.join(STYLES)}, got {style!r}")
    if osc_version not in VERSIONS:
        raise InputError(
            "osc_version", "", f"must be one of {', '.join(VERSIONS)}, got {osc_version!r}"
        )
    if top is not None and top < 1:
        raise InputError("top", "", f"must be >= 1, got {top}")
    run = read_run(Path(run_dir))
    out = Path(out_dir) if out_dir is not None else run.folder
    specs = specs_of_run(run, top)
    if style == "maneuver":
        for sp in specs:
            if not supported(sp):
                raise InputError(
                    "style",
                    "",
                    f"family {sp.family.name} (kind "
                    f"{sp.family.kind.name}) has no maneuver form; use "
                    "--style replay",
                )
    refuse_linked_paths(out)
    in_place = out.resolve() == run.folder.resolve()
    if not in_place and run.folder.resolve() in out.resolve().parents:
        # a catalog inside the run folder adds files its manifest does not list (verify
        # reports them) and a second catalog.json/run.json below the certified one
        raise InputError(
            "out",
            "",
            f"must be the run folder itself or outside it; {out} is inside {run.folder}",
        )
    if not in_place:  # another search run: its ranking, run.json and inputs/ replaced,
        # its search.sqlite and summary.json kept, the mixed folder certified
        other = next((n for n in SEARCH_RUN_FILES if (out / n).exists()), None)
        if other is not None:
            raise InputError(
                "out",
                "",
                f"{out} holds another search run ({other}); export into the run folder "
                "itself, a new folder or a catalog",
            )
        # another command's certified output (a compare, paper or tradeoff folder): its
        # report would be removed as stale and the mix certified by the new manifest
        refuse_certified_by_other(
            out, "export", lambda rel: rel == "catalog.json", "catalog.json (a catalog)"
        )
    writes = (
        EXPORT_WRITES
        if in_place
        else (*EXPORT_WRITES, "ranking.csv", "ranking.json", "run.json", f"{INPUTS_DIR}/")
    )
    refuse_if_changed(out, writes)
    if not in_place:  # what it copies from the run: certified there, so certified here
        refuse_if_source_changed(run.folder, COPIED_FROM_RUN, "a catalog")
    (out / "scenarios").mkdir(parents=True, exist_ok=True)
    (out / "roads").mkdir(parents=True, exist_ok=True)
    if not in_place:
        for name in ("ranking.csv", "ranking.json"):
            if (run.folder / name).is_file():
                atomic_write_bytes(out / name, (run.folder / name).read_bytes())
        copied = copy_record(run.folder, out)  # run.json and inputs/: rebuilt alike
        # inputs of an earlier export of another run into this catalog are removed (the
        # manifest would certify files no run.json entry names)
        for old in sorted((out / INPUTS_DIR).rglob("*"), key=lambda q: -len(q.parts)):
            rel = old.relative_to(out).as_posix()
            if old.is_file() and not old.is_symlink() and rel not in copied:
                old.unlink()
            elif old.is_dir() and not old.is_symlink() and not any(old.iterdir()):
                old.rmdir()
    files: dict[str, dict[str, Any]] = {}
    scenarios = []
    nets = {}
    for sp in specs:
        road_src = sp.road_path
        road_dst = out / "roads" / road_src.name
        if road_src.name not in nets:
            with atomic_path(road_dst) as tmp:
                shutil.copyfile(road_src, tmp)
            nets[road_src.name] = read_opendrive(road_dst)
            errs = xsd_errors(road_dst)
            if errs:  # the run's road (a search checks it first: settings'
                # refuse_unexportable_roads), bad input, not a fault of the export
                raise InputError(
                    road_src,
                    "",
                    f"not valid OpenDRIVE 1.7 ({errs[0]}): the catalog copies this road and "
                    "must pass the schema; fix the road (docs/roads.md)",
                )
            files[f"roads/{road_src.name}"] = {"role": "road"}
        path = out / "scenarios" / f"{sp.scenario_id}.xosc"
        write_xosc(sp, path, f"../roads/{road_src.name}", osc_version, style)
        errs = xsd_errors(path, osc_version)
        if errs:
            raise ExportError(f"{path}: not valid OpenSCENARIO {osc_version}: {errs[0]}")
        vru = sp.target.name in ("pedestrian", "bike")
        sem = semantic_errors(
            path,
            nets[road_src.name],
            _lanes(sp),
            tolerance_by_path={"Target_path": FOOTWAY_M, "Target_crossing": FOOTWAY_M}
            if vru
            else None,
        )
        if sem:
            raise ExportError(f"{path}: {sem[0]}")
        files[f"scenarios/{path.name}"] = {"role": "scenario", "scenario_id": sp.scenario_id}
        scenarios.append(
            {
                "rank": sp.rank,
                "scenario_id": sp.scenario_id,
                "family": sp.family.name,
                "environment": sp.environment_name,
                "sun_deg": None if sp.sun_deg is None else list(sp.sun_deg),
                "target": sp.target.name,
                "risk": sp.metrics.get("risk", 0.0),
                "log10_risk": sp.metrics.get("log10_risk", -300.0),
                "file": f"scenarios/{path.name}",
                "road": f"roads/{road_src.name}",
                "duration_s": sp.family.duration_s,
                "xsd": f"OpenSCENARIO {osc_version}: valid",
                "semantic_checks": "passed",
                "reason": sp.reason,
            }
        )
    # the catalog folder holds this export only: scenario and road files of an earlier
    # (larger) export and its simulation results are removed
    for sub, pattern in (("scenarios", "*.xosc"), ("roads", "*.xodr")):
        for old in (out / sub).glob(pattern):
            if f"{sub}/{old.name}" not in files:
                old.unlink()
    (out / "simulation.csv").unlink(missing_ok=True)
    if coverage:
        for p in _coverage_maps(specs, out / "coverage"):
            files[f"coverage/{p.name}"] = {"role": "coverage map"}
        for old in [*(out / "coverage").glob("*.npz"), *(out / "coverage").glob("*.png")]:
            if f"coverage/{old.name}" not in files and old.is_file() and not old.is_symlink():
                old.unlink()  # a map of an earlier export (another target or environment)
    for name in ("ranking.csv", "ranking.json"):
        if (out / name).is_file():
            files[name] = {"role": "ranking"}
    for rel, meta in files.items():
        p = out / rel
        meta.update({"bytes": p.stat().st_size, "sha256": sha256_of(p)})
    index = {
        "vehicle": specs[0].system.name if specs else run.vehicle_ref,
        "vehicle_ref": run.vehicle_ref,
        "osc_version": osc_version,
        "style": style,
        "scenarios": scenarios,
        "files": files,
        "search_settings": run.settings,
    }
    write_json(out / "catalog.json", index)
    write_manifest(out, writes)
    return index
