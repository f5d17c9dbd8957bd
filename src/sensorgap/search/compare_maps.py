"""The maps of an A-vs-B comparison, complete: what either run folder lacks is computed.

``complete_runs(run_a, run_b, out)`` gathers, for both vehicles, the near field
(``nearfield/``), the coverage maps (``coverage/<target>_<environment>/``) and the far-field
profiles (``farfield/<environment>/``). A piece the run folder holds is used as it is; a
piece it lacks is computed into ``out/<a|b>_<vehicle>/`` from the run's *recorded* inputs
(``search.runfolder``: its vehicle, environments and target classes, never a shipped preset
looked up by name) and listed in ``Completed.computed``. The input run folders are not
written to.

What is compared:

* coverage maps: every ``<target>_<environment>`` map either run holds, and a car map in
  every environment either run searched. Both maps of a pair are on one grid and target
  model: the first existing map (A before B) sets them, else the default job's
  (``COMPARE_GRID``, car bodies heading as the ego); a map on another grid is recomputed.
* far field: every environment of the coverage maps, with the default job's setup
  (``analysis.paper.FarFieldSetup``: a car body along the right lane of the R = 500 m
  motorway).
* difference maps (``out/difference/<key>/``): Pd_A - Pd_B of each pair on its common grid
  in the same environment, ``difference.npz``, ``difference.png`` (both maps and their
  difference on a diverging scale, both vehicles' sensors) and ``summary.json`` with the
  areas where only A, only B, both or neither detect (Pd >= ``DETECTS_PD``).

Two versions of one vehicle that differ only in their reaction model (``_sensing``) have
the same near field, maps and far field: each is computed once and written for both sides,
each side's files naming its own vehicle file and digest.

An environment or target class is taken from the run that computes the map; when that run
does not define it, from the other run (said in ``notes``); when both define it differently,
each vehicle is evaluated in its own run's definition and ``notes`` says so.
"""

from __future__ import annotations

import re
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.analysis.farfield import farfield
from sensorgap.analysis.farfield_outputs import write_farfield
from sensorgap.analysis.nearfield import write_nearfield
from sensorgap.analysis.paper import FarFieldSetup, ego_pose, target_path
from sensorgap.atomic import atomic_write_bytes
from sensorgap.config import EnvironmentConfig, TargetConfig
from sensorgap.config.presets import shipped_road
from sensorgap.coverage import GridSpec, Scene
from sensorgap.coverage.outputs import compute_coverage, read_coverage_npz, write_coverage
from sensorgap.coverage.plot import comparison_figure, save_figure
from sensorgap.errors import InputError
from sensorgap.filesio import is_temporary, write_json, write_npz
from sensorgap.models import Conditions, System
from sensorgap.roads import read_opendrive
from sensorgap.search.compare import side_labels
from sensorgap.search.runfolder import RunFolder, open_run, read_json_file

#: The default job's coverage grid (``jobs.DEFAULT_GRID``): x from, x to, y from, y to, cell
#: size, m.
COMPARE_GRID = (-60.0, 260.0, -50.0, 50.0, 0.5)
#: Heading of the coverage maps' target bodies relative to the ego, deg
#: (``jobs.COVERAGE_HEADING_DEG``).
COMPARE_HEADING_DEG = 0.0
#: Pd from which a vehicle counts as detecting a target in a cell.
DETECTS_PD = 0.5
#: The target class of the maps made for searched environments.
DEFAULT_TARGET = "car"


def slug(name: str) -> str:
    """A vehicle name as a file-name part (letters, digits, ``.``, ``_``, ``-``; no leading
    dot, and ``_`` added to one that would read like a temporary or journal file, which
    verify takes for a left-over: hostile round 36's vehicle ``B.tmp``)."""
    text = re.sub(r"[^A-Za-z0-9._-]+", "_", name).strip("_").lower().lstrip(".") or "vehicle"
    return f"{text}_" if is_temporary(text) else text


@dataclass(frozen=True)
class MapModel:
    """A coverage map's grid and target model (``heading_deg`` None: points)."""

    grid: tuple[float, float, float, float, float]
    heading_deg: float | None

    def spec(self, height_m: float) -> GridSpec:
        """The grid at a target's reference height, m."""
        xmin, xmax, ymin, ymax, res = self.grid
        return GridSpec(xmin, xmax, ymin, ymax, res, height_m)


DEFAULT_MODEL = MapModel(COMPARE_GRID, COMPARE_HEADING_DEG)


@dataclass
class SideMaps:
    """One vehicle's pieces: where each lies (its run folder or the comparison's)."""

    tag: str
    run: RunFolder
    #: the side's label in the report (``search.compare.side_labels``: the vehicle's name,
    #: with the tag and run folder when both vehicles have the same name)
    name: str
    #: the folder computed pieces go to (``out/<tag>_<vehicle>``)
    made: Path
    #: folder holding nearfield.json / nearfield.png (None: could not be made)
    nearfield: Path | None = None
    #: coverage map key (``<target>_<environment>``) -> folder with coverage.npz
    coverage: dict[str, Path] = field(default_factory=dict)
    #: environment -> far-field folder (summary.json, farfield.csv, farfield.png)
    farfield: dict[str, Path] = field(default_factory=dict)
    #: what was computed for this comparison, in words
    computed: list[str] = field(default_factory=list)


@dataclass
class Completed:
    """Both vehicles' pieces, the difference maps (key -> folder) and notes."""

    a: SideMaps
    b: SideMaps
    keys: list[str]
    environments: list[str]
    differences: dict[str, Path]
    notes: list[str]


def _map_model(summary: dict[str, Any]) -> MapModel | None:
    """The grid and target model of a coverage ``summary.json`` (None: occluders or a
    model this comparison does not make)."""
    if summary.get("occluders"):
        return None
    g = summary.get("grid", {})
    try:
        grid = (
            float(g["xmin"]),
            float(g["xmax"]),
            float(g["ymin"]),
            float(g["ymax"]),
            float(g["resolution_m"]),
        )
    except (KeyError, TypeError, ValueError):
        return None
    model = str(summary.get("target_model", ""))
    if model.startswith("point"):
        return MapModel(grid, None)
    m = re.search(r"heading (-?[0-9.]+) deg", model)
    return MapModel(grid, float(m.group(1))) if m else None


def _existing_maps(run: RunFolder) -> dict[str, tuple[Path, dict[str, Any]]]:
    """key -> (folder, summary) of the coverage maps a run folder holds."""
    out = {}
    cov = run.folder / "coverage"
    for s in sorted(cov.glob("*/summary.json")) if cov.is_dir() else []:
        if (s.parent / "coverage.npz").is_file():
            d = read_json_file(s)
            if isinstance(d, dict):
                load_map(s.parent)  # unreadable: bad input before anything is computed
                out[s.parent.name] = (s.parent, d)
    return out


def _check_farfield_identity(path: Path, system: System | None, env_name: str) -> None:
    """A run's far field (``path``: its ``summary.json``) is of this run's vehicle and of
    the environment its folder names, else ``InputError`` (hostile round 24: another
    vehicle's far field, put into a run, was compared as this one's)."""
    d = read_json_file(path)
    if not isinstance(d, dict):
        raise InputError(path, "", "expected a JSON object")
    if system is not None and d.get("vehicle") != system.name:
        raise InputError(
            path,
            "vehicle",
            f"{str(d.get('vehicle'))[:64]!r} is not this run's vehicle ({system.name!r}); "
            "compute the far field with `sensorgap farfield --vehicle <the run's vehicle>`",
        )
    if d.get("environment") != env_name:
        raise InputError(
            path,
            "environment",
            f"{str(d.get('environment'))[:64]!r}, in the folder farfield/{env_name[:64]}",
        )


def _key_parts(key: str, summary: dict[str, Any] | None) -> tuple[str, str]:
    """(target, environment) of a coverage map key (its summary.json when given)."""
    if (
        summary
        and isinstance(summary.get("target"), str)
        and isinstance(summary.get("environment"), str)
    ):
        return summary["target"], summary["environment"]
    target, _, env = key.partition("_")
    return target, env


def _system(side: SideMaps) -> System | None:
    try:
        return side.run.system()
    except InputError:
        return None


def _lookup(side: SideMaps, other: SideMaps, kind: str, name: str, notes: list[str]) -> Any:
    """An environment or target class of ``side``'s run, else of ``other``'s (noted)."""

    def table(s: SideMaps) -> dict[str, Any]:
        try:
            return dict(s.run.environments() if kind == "environment" else s.run.targets())
        except InputError:
            return {}

    own, theirs = table(side), table(other)
    note = ""
    found = None
    if name in own:
        found = own[name]
        if name in theirs and theirs[name] != own[name]:
            note = (
                f"{kind} '{name}' is defined differently by the two runs: each vehicle "
                "is evaluated in its own run's definition"
            )
    elif name in theirs:
        found = theirs[name]
        note = (
            f"{kind} '{name}': not in the recorded inputs of {side.run.folder.name}; "
            f"those of {other.run.folder.name} are used for both"
        )
    if note and note not in notes:
        notes.append(note)
    return found


def _sensing(system: System | None) -> str | None:
    """What a vehicle's near field, coverage maps and far field depend on: its
    configuration but for the reaction model (None: not recorded). Two versions of one
    vehicle that differ only in how they react (the usual comparison of a reaction
    model) have the same pieces: each computed once, written for both (a map's and a
    far field's files with each side's own vehicle file and digest; the near field
    names none and is copied)."""
    if system is None:
        return None
    return system.config.model_dump_json(exclude={"reaction"})


def _copy_piece(src: Path, dst: Path) -> None:
    """A piece computed for one side (a folder of files), copied for the other: each file
    written atomically, over the one an earlier comparison into the same folder left."""
    for file in sorted(src.rglob("*")):
        if file.is_file():
            target = dst / file.relative_to(src)
            target.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_bytes(target, file.read_bytes())


def _farfield_one(
    system: System,
    env: EnvironmentConfig,
    target: TargetConfig,
    out_dir: Path,
    computed: Any = None,
) -> Any:
    """The default job's far field of a car body (``jobs._farfield``) for one
    environment, from given (recorded) definitions; returns the profile. ``computed``: the
    profile of a twin vehicle (``_sensing``) in the same environment, written for this
    one instead of computed again."""
    setup = FarFieldSetup()
    net = read_opendrive(shipped_road(setup.road))
    pose = ego_pose(net, setup)
    scene = Scene(system, target, Conditions.from_config(env, pose.heading))
    ff = (
        computed
        if computed is not None
        else farfield(scene, target_path(net, setup), pose, setup.length_m, bodies=True)
    )
    write_farfield(
        scene,
        ff,
        out_dir,
        f"{system.name}, {env.name}: car body along the right lane",
        extra={
            "setup": setup.__dict__,
            "target_model": "body (coverage.body), heading along the lane",
        },
        bodies=True,
    )
    return ff


def _label(side: SideMaps, folder: Path, out: Path) -> str:
    """A piece's folder without the machine's paths: relative to the comparison's folder
    ``out`` when made there, else ``run <run folder name>: <path in the run>``."""
    try:
        return folder.resolve().relative_to(Path(out).resolve()).as_posix()
    except ValueError:
        return (
            f"run {side.run.folder.name}: "
            f"{folder.resolve().relative_to(side.run.folder.resolve()).as_posix()}"
        )


def _difference(
    key: str,
    a: SideMaps,
    b: SideMaps,
    sys_a: System,
    sys_b: System,
    env: EnvironmentConfig | None,
    out_dir: Path,
) -> None:
    """difference.npz / .png / summary.json of the pair ``key`` (one grid)."""
    pa, x, y, res = load_map(a.coverage[key])
    pb = load_map(b.coverage[key])[0]
    diff = pa - pb
    cell = res * res
    da, db = pa >= DETECTS_PD, pb >= DETECTS_PD
    areas = {
        "only_a_m2": float(np.count_nonzero(da & ~db) * cell),
        "only_b_m2": float(np.count_nonzero(db & ~da) * cell),
        "both_m2": float(np.count_nonzero(da & db) * cell),
        "neither_m2": float(np.count_nonzero(~da & ~db) * cell),
    }
    out_dir.mkdir(parents=True, exist_ok=True)
    write_npz(
        out_dir / "difference.npz",
        {"x": x, "y": y, "pd_a": pa, "pd_b": pb, "difference": diff, "resolution": np.array(res)},
    )
    spec = GridSpec(
        float(x[0]) - res / 2,
        float(x[-1]) + res / 2,
        float(y[0]) - res / 2,
        float(y[-1]) + res / 2,
        res,
        0.0,
    )
    cond = None if env is None else Conditions.from_config(env)
    fig = comparison_figure(pa, pb, spec, sys_a, sys_b, key, conditions=cond)
    save_figure(fig, out_dir / "difference.png", dpi=90)
    write_json(
        out_dir / "summary.json",
        {
            "map": key,
            "vehicle_a": a.name,
            "vehicle_b": b.name,
            "coverage_a": _label(a, a.coverage[key], out_dir.parent.parent),
            "coverage_b": _label(b, b.coverage[key], out_dir.parent.parent),
            "detects_pd": DETECTS_PD,
            "cell_m": res,
            "difference": "Pd_A - Pd_B per cell (exact Pd at the cell centres)",
            "max_difference": float(diff.max()),
            "min_difference": float(diff.min()),
            "area_m2": areas,
            "files": ["difference.npz", "difference.png", "summary.json"],
        },
    )


def complete_runs(run_a: Path, run_b: Path, out: Path, workers: int = 2) -> Completed:
    """Gather or compute both vehicles' near field, coverage maps and far field and the
    difference maps into ``out`` (see the module docstring)."""
    ra, rb = open_run(Path(run_a), ranking=False), open_run(Path(run_b), ranking=False)
    names = []
    for run in (ra, rb):
        try:
            names.append(run.system().name)
        except InputError:
            names.append(run.folder.name)
    labels = side_labels(names[0], names[1], ra.folder, rb.folder)
    sides = [
        SideMaps(tag, run, label, Path(out) / f"{tag}_{slug(name)}")
        for tag, run, name, label in zip(("a", "b"), (ra, rb), names, labels, strict=True)
    ]
    a, b = sides
    notes: list[str] = []
    systems = {s.tag: _system(s) for s in sides}
    for s in sides:
        if systems[s.tag] is None:
            notes.append(
                f"{s.run.folder.name}: the vehicle is not recorded (no run.json "
                "or ranking.json): nothing can be computed for it"
            )

    existing = {s.tag: _existing_maps(s.run) for s in sides}
    # the same vehicle but for its reaction model: what is computed for one side serves
    # the other (``_sensing``)
    twins = _sensing(systems["a"]) is not None and _sensing(systems["a"]) == _sensing(systems["b"])

    # near field
    made_nearfield: Path | None = None
    for s in sides:
        own = s.run.folder / "nearfield"
        sysm = systems[s.tag]
        if (own / "nearfield.json").is_file():
            s.nearfield = own
        elif sysm is not None:
            if twins and made_nearfield is not None:
                _copy_piece(made_nearfield, s.made / "nearfield")
            else:
                write_nearfield(sysm, s.made / "nearfield")
                made_nearfield = s.made / "nearfield"
            s.nearfield = s.made / "nearfield"
            s.computed.append("near field")

    # coverage maps: the keys and their (grid, target model)
    keys: dict[str, tuple[str, str]] = {}
    for s in sides:
        for key, (_, summ) in existing[s.tag].items():
            keys.setdefault(key, _key_parts(key, summ))
    for s in sides:
        for env in s.run.settings.get("environments", []) or []:
            keys.setdefault(f"{DEFAULT_TARGET}_{env}", (DEFAULT_TARGET, str(env)))
    todo: list[tuple[SideMaps, str, Scene, MapModel]] = []
    #: per job of ``todo``, what its map depends on beyond the vehicle (twins: one map)
    inputs: list[tuple[str, str, str, MapModel]] = []
    for key in sorted(keys, key=lambda k: (k not in existing["a"], k not in existing["b"], k)):
        target_name, env_name = keys[key]
        models = [_map_model(existing[s.tag][key][1]) for s in sides if key in existing[s.tag]]
        model = next((m for m in models if m is not None), DEFAULT_MODEL)
        for s, other in ((a, b), (b, a)):
            have = existing[s.tag].get(key)
            if have is not None and _map_model(have[1]) == model:
                s.coverage[key] = have[0]
                continue
            sysm = systems[s.tag]
            env = _lookup(s, other, "environment", env_name, notes)
            target = _lookup(s, other, "target", target_name, notes)
            if sysm is None or env is None or target is None:
                note = (
                    f"coverage {key}: environment or target class defined by neither "
                    "run: not compared"
                )
                if sysm is not None and note not in notes:
                    notes.append(note)
                continue
            todo.append((s, key, Scene(sysm, target, Conditions.from_config(env)), model))
            inputs.append((key, env.model_dump_json(), target.model_dump_json(), model))

    # a twin's map of the same inputs: the first one's computed map (index into todo)
    first = {inp: i for i, inp in reversed(list(enumerate(inputs)))} if twins else {}
    copy_of = [first.get(inp, i) for i, inp in enumerate(inputs)]

    def one(job: tuple[SideMaps, str, Scene, MapModel]) -> Any:
        _, _, scene, model = job
        return compute_coverage(
            scene, model.spec(scene.target.reference_height_m), heading_deg=model.heading_deg
        )

    own_jobs = [i for i in range(len(todo)) if copy_of[i] == i]
    with ThreadPoolExecutor(max_workers=max(1, workers)) as pool:
        covs = dict(zip(own_jobs, pool.map(one, [todo[i] for i in own_jobs]), strict=True))
    for i, (s, key, scene, model) in enumerate(todo):  # figures: this thread
        folder = s.made / "coverage" / slug(key)
        write_coverage(  # a twin's map written with this side's vehicle (provenance)
            scene,
            model.spec(scene.target.reference_height_m),
            folder,
            heading_deg=model.heading_deg,
            cov=covs[copy_of[i]],
        )
        s.coverage[key] = folder
        s.computed.append(f"coverage {key}")
    both = [k for k in sorted(keys) if k in a.coverage and k in b.coverage]

    # far field: every environment of the maps
    envs = sorted({keys[k][1] for k in keys}, key=lambda e: (e != "clear", e))
    made_farfield: dict[tuple[str, str], Any] = {}  # (environment, target) -> profile
    for s, other in ((a, b), (b, a)):
        for env_name in envs:
            own = s.run.folder / "farfield" / env_name
            sysm = systems[s.tag]
            if (own / "summary.json").is_file() and (own / "farfield.csv").is_file():
                _check_farfield_identity(own / "summary.json", sysm, env_name)
                s.farfield[env_name] = own
                continue
            env = _lookup(s, other, "environment", env_name, notes)
            target = _lookup(s, other, "target", DEFAULT_TARGET, notes)
            if sysm is None or env is None or target is None:
                continue
            same = (env.model_dump_json(), target.model_dump_json())
            made_farfield[same] = _farfield_one(
                sysm,
                env,
                target,
                s.made / "farfield" / slug(env_name),
                made_farfield.get(same) if twins else None,
            )
            s.farfield[env_name] = s.made / "farfield" / slug(env_name)
            s.computed.append(f"far field {env_name}")

    # difference maps
    diffs: dict[str, Path] = {}
    sys_a, sys_b = systems["a"], systems["b"]
    if sys_a is not None and sys_b is not None:
        for key in both:
            env = _lookup(a, b, "environment", keys[key][1], notes)
            if not _same_grid(a.coverage[key], b.coverage[key]):
                notes.append(
                    f"coverage {key}: the two maps are on different grids: no difference map"
                )
                continue
            _difference(key, a, b, sys_a, sys_b, env, Path(out) / "difference" / slug(key))
            diffs[key] = Path(out) / "difference" / slug(key)
    return Completed(a, b, both, envs, diffs, notes)


def load_map(folder: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """(pd, x, y, cell size m) of ``folder/coverage.npz``; unreadable or inconsistent ->
    ``InputError`` naming the file."""
    return read_coverage_npz(folder / "coverage.npz")


def _same_grid(fa: Path, fb: Path) -> bool:
    pa, xa, ya, _ = load_map(fa)
    pb, xb, yb, _ = load_map(fb)
    return pa.shape == pb.shape and bool(np.allclose(xa, xb)) and bool(np.allclose(ya, yb))


__all__ = ["COMPARE_GRID", "Completed", "SideMaps", "complete_runs", "slug"]
