"""Command line: thin wrappers over the library. Bad input -> one line, exit 2."""

from __future__ import annotations

import argparse
import errno
import json
import math
import os
import shutil
import signal
import sys
import traceback
from collections.abc import Callable, Sequence
from contextlib import ExitStack, suppress
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from sensorgap.runtime import single_blas_thread

single_blas_thread()  # before numpy is imported (by filesio): see its docstring

from sensorgap.atomic import removed_on_error
from sensorgap.config.common import parse_decimal, parse_integer
from sensorgap.errors import InputError, clip, cut_name, notes_after_success
from sensorgap.filesio import (
    MANIFEST_NAME,
    refuse_certified_by_other,
    refuse_certified_out,
    refuse_foreign_outputs,
    refuse_if_changed,
    refuse_inside_certified,
    same_file,
    write_manifest,
)
from sensorgap.locks import folder_lock, held_until_done
from sensorgap.plugins import load_plugins
from sensorgap.runtime import (
    StdoutUnwritable,
    check_numba_environment,
    guarded_stdout,
    standard_streams,
    tune_allocator,
)

if TYPE_CHECKING:
    from _typeshed import SupportsWrite

    from sensorgap.coverage import Scene
    from sensorgap.coverage.occluders import Occluder

EXIT_INPUT = 2
# Input limits (docs/limits.md): the worst accepted input stays within ~4 GiB (measured:
# benchmarks/bench_limits.py). Those of coverage maps and probe points are the library's
# too (``coverage.limits``, ``coverage.pointsio``).
#: nearfield: resolution range, m.
NEARFIELD_RESOLUTION_M = (0.02, 1.0)
#: farfield: path length range, m.
MAX_FARFIELD_LENGTH_M = 10_000.0
#: The shortest far-field path, m: a few sample steps (a subnormal length drew a figure of
#: zero width, with matplotlib's warning on standard error: hostile round eighteen, F4).
MIN_FARFIELD_LENGTH_M = 1.0
EXIT_INTERNAL = 1
#: What each analysis command writes into its --out folder (besides manifest.json): an
#: existing --out must hold nothing else (``filesio.refuse_foreign_outputs``).
ANALYSIS_WRITES = {
    "coverage": ("coverage.npz", "coverage.png", "summary.json"),
    "nearfield": ("nearfield.json", "nearfield.png"),
    "farfield": ("farfield.csv", "farfield.png", "levels.csv", "summary.json"),
    "corridor": ("corridor.csv", "corridor.png", "summary.json"),
}
#: Every file an analysis command or a command with one named output writes at the top of
#: its folder: a manifest listing one of them beside an analysis command's own files is
#: not a folder of the user's files (``filesio.refuse_foreign_outputs``).
_COMMAND_FILES = frozenset(
    {
        *(name for names in ANALYSIS_WRITES.values() for name in names),
        "paper.md",
        "tradeoff.csv",
        "comparison.json",
        "report.html",
        "report.md",
    }
)
_GLUED_OPTIONS = {
    "--extent",
    "--height",
    "--heading",
    "--ego-s",
    "--speed",
    "--sun",
    "--ego-lane",
    "--target-lane",
    "--lanes",
    "--start",
    "--goal",
}


class _Terminated(KeyboardInterrupt):
    """Ctrl-C, SIGTERM (``kill``, ``timeout``) or SIGHUP (the terminal closed) as an
    interrupt of the main thread: the command unwinds, so a file being written leaves no
    temporary file (``atomic.atomic_path``) and a folder is put back as it was
    (``atomic.removed_on_error``); the exit code is 128 + the signal's number."""

    def __init__(self, signum: int = signal.SIGTERM) -> None:
        super().__init__()
        self.signum = int(signum)


#: The stop signals received by this process (``_terminate``): an exception that unwinds
#: the command after one arrived is its interruption, whatever its type.
_RECEIVED: list[int] = []


#: Functions the interpreter calls from C, where an exception raised is printed as
#: "Exception ignored in ..." and lost: weak-reference callbacks (the ``remove`` closures
#: of ``weakref``'s dictionaries and sets) and finalizers (``__del__``).
_SWALLOWING = {
    ("weakref.py", "remove"),
    ("_weakrefset.py", "_remove"),
    ("weakref.py", "__call__"),  # weakref.finalize
}


def _in_compiler_callback(frame: Any) -> bool:
    """True when the main thread runs Python code where an exception raised is printed
    and lost instead of stopping the command: under llvmlite (numba's compiler), where a
    C library may have called back into Python ("Exception ignored on calling ctypes
    callback function"), and in a weak-reference callback or a finalizer the interpreter
    called (``_SWALLOWING``, ``__del__``: hostile round twenty-one, a Ctrl-C during a
    ``WeakKeyDictionary`` callback was lost and the command ran to its end)."""
    f = frame
    while f is not None:
        code = f.f_code
        name = os.path.basename(code.co_filename)
        if (
            "llvmlite" in code.co_filename
            or code.co_name == "__del__"
            or (name, code.co_name) in _SWALLOWING
        ):
            return True
        f = f.f_back
    return False


def _terminate(signum: int, frame: Any) -> None:
    """Stop the command (``_Terminated``). Inside numba's compiler the signal is sent
    again 0.1 s later instead (hostile round seventeen: raised in a ctypes callback, it
    was swallowed with a traceback on stderr and the command ran to its end)."""
    if _RECEIVED:
        # the command is stopping already: a second signal must not stop its restore
        # half-way (hostile round nineteen, F6: ``timeout`` and a terminal signal the
        # process group too, so the process got SIGTERM twice; raised again in the put
        # back, it left the restore folder and a folder failing verify)
        return
    if _in_compiler_callback(frame):
        import threading

        timer = threading.Timer(0.1, os.kill, (os.getpid(), signum))
        timer.daemon = True
        timer.start()
        return
    _RECEIVED.append(int(signum))
    raise _Terminated(signum)


#: The signals that stop a command as Ctrl-C does (``_Terminated``): SIGTERM, and SIGHUP
#: (hostile round twelve: a closed terminal killed the command half-way, exit 129, its
#: temporary files and a half-written folder left).
_STOP_SIGNALS = tuple(
    getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)
)


def _decimal(text: str) -> float:
    return parse_decimal(text)


def _integer(text: str) -> int:
    return parse_integer(text)


_decimal.__name__ = "number"  # argparse: "invalid number value: '1_0'"
_integer.__name__ = "integer"


def _float_list(text: str, n: int, option: str) -> list[float]:
    parts = text.split(",")
    try:
        vals = [parse_decimal(p) for p in parts]
    except ValueError:
        vals = []
    if len(vals) != n or not all(math.isfinite(v) for v in vals):
        raise InputError(option, "", f"expected {n} finite comma-separated numbers, got {text!r}")
    return vals


def _positive(value: float, option: str) -> float:
    if not (math.isfinite(value) and value > 0.0):
        raise InputError(option, "", f"must be a finite number > 0, got {value!r}")
    return value


def _scene(args: argparse.Namespace, ego_heading_rad: float = 0.0) -> Scene:
    from sensorgap.config import load_environment, load_target
    from sensorgap.coverage import Scene
    from sensorgap.models import Conditions, load_system

    system = load_system(args.vehicle)
    env = load_environment(
        args.environment, Path(args.environments_file) if args.environments_file else None
    )
    target = load_target(args.target)
    return Scene(system, target, Conditions.from_config(env, ego_heading_rad))


def cmd_probe(args: argparse.Namespace) -> int:
    """Per-sensor SNR/Pd and fused Pd at points read from a CSV."""
    from sensorgap.atomic import atomic_write_bytes
    from sensorgap.coverage import evaluate_points
    from sensorgap.coverage.outputs import probe_csv
    from sensorgap.coverage.pointsio import check_point_count, read_points_csv

    if args.out and os.path.basename(args.out) in ("", ".", ".."):
        # pathlib drops a trailing "/" (and "/."): newdir/ was written as the file newdir
        raise InputError(
            "--out",
            "",
            f"{args.out} names a folder (a path ending in '{os.sep}', '.' or '..'); probe writes "
            "one CSV file: give its path, e.g. "
            f"{os.path.join(args.out, 'probe.csv')}",
        )
    if args.out and same_file(args.out, args.points):
        raise InputError(
            "--out", "", f"is the --points file {args.points}: writing would overwrite the input"
        )
    if args.out:  # a file no manifest lists: a certified folder would fail its verify
        refuse_certified_out(Path(args.out).parent, "probe")
    scene = _scene(args)
    pts = read_points_csv(
        Path(args.points),
        default_z=scene.target.reference_height_m,
        heights=args.heading is None,
    )
    check_point_count(
        len(pts),
        len(scene.sensors),
        args.points,
        bodies=" with --heading" if args.heading is not None else None,
        remedy="split the file",
    )
    if args.heading is None:
        data = probe_csv(evaluate_points(scene, pts))
    else:
        data = _probe_bodies(scene, pts, args.heading)
    if args.out:  # a failed write leaves no folder it made for the file
        # one file of a user's folder, renamed into place: the folder is not locked
        with removed_on_error(Path(args.out).parent, only=(Path(args.out).name,), lock=False):
            atomic_write_bytes(args.out, data)
    else:
        sys.stdout.write(data.decode("utf-8"))
    return 0


def _check_heading(heading_deg: float) -> None:
    """``--heading``: a finite angle within +-360 deg (as an ``--occluder`` heading)."""
    from sensorgap.coverage.limits import check_heading

    check_heading(heading_deg, "--heading")


def _probe_bodies(scene: Scene, pts: Any, heading_deg: float) -> bytes:
    """``probe --heading``: target bodies centred at the points' x, y (z is ignored: a body
    stands on the ground) at a heading relative to the ego (deg): per sensor the visible
    fraction of the facing outline and Pd, then the fused Pd (``coverage.body``)."""
    import numpy as np

    from sensorgap.coverage.body import body_per_sensor_pd
    from sensorgap.filesio import csv_bytes
    from sensorgap.models.geometry import heading_rad

    _check_heading(heading_deg)
    x, y = pts[:, 0], pts[:, 1]
    # the scene carries its sun (its SNRs include the glare of that sun)
    pd, frac = body_per_sensor_pd(scene, x, y, np.full(len(x), heading_rad(heading_deg)))
    fused = -np.expm1(np.sum(np.log1p(-np.minimum(pd, np.nextafter(1.0, 0.0))), axis=0))
    cols = ["x", "y", "heading_deg"]
    data = [x, y, np.full(len(x), heading_deg)]
    for i, sn in enumerate(scene.sensors):
        cols += [f"{sn.id}.visible", f"{sn.id}.pd"]
        data += [frac[i], pd[i]]
    return csv_bytes([*cols, "pd"], [*data, fused + 0.0])


def _check_run_input(out: str, command: str, vehicle: str, name: str | None) -> None:
    """``--out`` of ``coverage`` / ``nearfield`` inside a search run (``RUN/coverage/<name>``,
    ``RUN/nearfield``: what its report reads) must be for the run's vehicle, and a map's
    folder named ``<target>_<environment>`` after what is computed (hostile round sixteen:
    another vehicle's map was certified into a run); refused before any work."""
    from sensorgap.filesio import certified_parent
    from sensorgap.search.runfolder import STORE_FILE, open_run

    found = certified_parent(out, command)
    if found is None or not (found[0] / STORE_FILE).is_file():
        return
    run = open_run(found[0], ranking=False)
    if not run.vehicle_ref:
        return
    theirs = run.system().name
    if theirs != vehicle:
        raise InputError(
            "--out",
            "",
            f"{found[0].name}/{found[1]} is a report input of a run of {theirs!r}, not of "
            f"{vehicle!r}: give --vehicle the run's vehicle, or another --out",
        )
    if name is not None and Path(out).name != name:
        raise InputError(
            "--out",
            "",
            f"a run's coverage maps are named <target>_<environment>: this one is "
            f"{found[0].name}/coverage/{name}, not {found[1]}",
        )


def cmd_coverage(args: argparse.Namespace) -> int:
    """A coverage grid, heat map and summary into --out."""
    from sensorgap.coverage import limits
    from sensorgap.coverage.limits import CLI_NAMES
    from sensorgap.coverage.outputs import write_coverage
    from sensorgap.coverage.pointsio import MAX_HEIGHT_M

    refuse_foreign_outputs(args.out, ANALYSIS_WRITES["coverage"], "coverage", _COMMAND_FILES)
    refuse_inside_certified(args.out, "coverage")
    limits.check_workers(args.workers, CLI_NAMES)
    extent = _float_list(args.extent, 4, "--extent")
    res = limits.check_resolution(args.resolution, "--resolution")
    if args.heading is not None:
        _check_heading(args.heading)
    nx, ny = limits.grid_cells(extent, res, args.heading is not None, CLI_NAMES, shown=args.extent)
    cells = nx * ny
    scene = _scene(args)
    _check_run_input(args.out, "coverage", scene.system.name, f"{args.target}_{args.environment}")
    height = scene.target.reference_height_m if args.height is None else args.height
    if not (math.isfinite(height) and 0.0 <= height <= MAX_HEIGHT_M):
        raise InputError(
            "--height",
            "",
            f"must be within 0..{MAX_HEIGHT_M:g} m (above the road plane the "
            f"vehicle stands on: the models know no terrain), got {height!r}",
        )
    if args.per_sensor:
        limits.check_per_sensor(cells, len(scene.sensors), CLI_NAMES)
    grid = limits.grid_spec(extent, res, nx, ny, height)
    limits.check_occluder_count(len(args.occluder), CLI_NAMES)  # before any is parsed
    occluders = [_occluder(text) for text in args.occluder]
    limits.check_occluders(
        occluders, args.heading, scene.system.config.vehicle, CLI_NAMES, shown=args.occluder
    )
    if args.heading is not None:
        limits.check_body_work(cells, len(scene.sensors), len(occluders), CLI_NAMES)
    xmin, xmax, ymin, ymax = extent
    clipped = (grid.xmax, grid.ymax)
    with removed_on_error(args.out):
        summary = write_coverage(
            scene,
            grid,
            Path(args.out),
            per_sensor=args.per_sensor,
            workers=args.workers,
            heading_deg=args.heading,
            occluders=occluders,
        )
        write_manifest(args.out)
    lv = summary["area_m2_by_level"]
    note = (
        ""
        if clipped == (xmax, ymax)
        else f" (extent clipped to whole cells: x {xmin:g}..{clipped[0]:g}, y {ymin:g}.."
        f"{clipped[1]:g} m)"
    )
    print(
        f"{args.out}: {grid.nx}x{grid.ny} cells, area Pd=1 {lv['pd=1.0']:.0f} m2, "
        f"Pd>0 {lv['pd>0']:.0f} m2{note}"
    )
    return 0


def _occluder(text: str) -> Occluder:
    """``KIND@X,Y,HEADING`` -> an occluder sized as the target class KIND."""
    from sensorgap.config import load_target
    from sensorgap.coverage.occluders import MAX_OCCLUDER_M, Occluder
    from sensorgap.models.geometry import heading_rad

    kind, sep, rest = text.partition("@")
    if not sep:
        raise InputError(
            "--occluder", "", f"must be KIND@X,Y,HEADING (e.g. truck@15,-3.5,0), got {text!r}"
        )
    x, y, heading = _float_list(rest, 3, "--occluder")
    if not (abs(x) <= MAX_OCCLUDER_M and abs(y) <= MAX_OCCLUDER_M and abs(heading) <= 360.0):
        raise InputError(
            "--occluder",
            "",
            f"X, Y within +-{MAX_OCCLUDER_M:g} m and HEADING within +-360 deg, got {text!r}",
        )
    try:
        target = load_target(kind.strip())
    except InputError as e:
        raise InputError("--occluder", "", f"unknown occluder kind {kind!r}: {e}") from None
    return Occluder.of_target(target, x, y, heading_rad(heading))


def cmd_nearfield(args: argparse.Namespace) -> int:
    """Near-field blind spots (exact polygons and grid) into --out."""
    from sensorgap.analysis.nearfield import write_nearfield
    from sensorgap.models import load_system

    refuse_foreign_outputs(args.out, ANALYSIS_WRITES["nearfield"], "nearfield", _COMMAND_FILES)
    refuse_inside_certified(args.out, "nearfield")
    res = _positive(args.resolution, "--resolution")
    lo, hi = NEARFIELD_RESOLUTION_M
    if not lo <= res <= hi:
        raise InputError("--resolution", "", f"must be within {lo:g}..{hi:g} m, got {res!r}")
    system = load_system(args.vehicle)
    _check_run_input(args.out, "nearfield", system.name, None)
    with removed_on_error(args.out):
        summary = write_nearfield(system, Path(args.out), res)
        write_manifest(args.out)
    bs = summary["blind_spot_m2"]
    print(
        f"{args.out}: blind spots {bs['exact']:.2f} m2 exact, {bs['grid']:.2f} m2 on the "
        f"{res:g} m grid; no sensor at any height "
        f"{summary['unseen_any_height_m2']['exact']:.2f} m2 in all"
    )
    return 0


def cmd_farfield(args: argparse.Namespace) -> int:
    """Pd along a target lane ahead of the ego (Table IV levels) into --out."""
    from sensorgap.analysis.farfield_outputs import write_farfield
    from sensorgap.analysis.paper import FarFieldSetup, run_farfield
    from sensorgap.config.presets import resolve_road, shipped_road
    from sensorgap.models import load_system
    from sensorgap.roads import read_opendrive

    refuse_foreign_outputs(args.out, ANALYSIS_WRITES["farfield"], "farfield", _COMMAND_FILES)
    refuse_inside_certified(args.out, "farfield")
    length = _positive(args.length, "--length")
    if not MIN_FARFIELD_LENGTH_M <= length <= MAX_FARFIELD_LENGTH_M:
        raise InputError(
            "--length",
            "",
            f"must be {MIN_FARFIELD_LENGTH_M:g} .. {MAX_FARFIELD_LENGTH_M:g} m, got {length!r}",
        )
    setup = FarFieldSetup(
        road=args.road,
        road_id=args.road_id,
        ego_lane=args.ego_lane,
        target_lane=args.target_lane,
        ego_s_m=args.ego_s,
        length_m=length,
        target=args.target,
    )
    text = str(args.road)
    shipped = not (text.endswith(".xodr") or "/" in text)  # a name: one of the shipped roads
    net = read_opendrive(shipped_road(text) if shipped else resolve_road(text))
    road = net.road(args.road_id)
    if not (0.0 <= args.ego_s <= road.length):
        raise InputError(
            "--ego-s",
            "",
            f"must be within 0..{road.length:g} m of road {args.road_id}, got {args.ego_s!r}",
        )
    for opt, lane in (("--ego-lane", args.ego_lane), ("--target-lane", args.target_lane)):
        if not net.lane_exists(args.road_id, lane, args.ego_s):
            raise InputError(
                opt,
                "",
                f"lane {lane} does not exist on road {args.road_id} at s = {args.ego_s:g} m",
            )
    system = load_system(args.vehicle)
    bodies = args.target_model == "body"
    with removed_on_error(args.out):
        scene, ff = run_farfield(system, args.environment, setup, net, bodies=bodies)
        write_farfield(
            scene,
            ff,
            Path(args.out),
            f"{system.name}, {args.environment}: "
            f"{args.target} ({args.target_model}) on lane {args.target_lane}",
            extra={"setup": setup.__dict__, "target_model": _target_model(bodies)},
            bodies=bodies,
        )
        write_manifest(args.out)
    print(", ".join(f"{k} {v:.0f} m" for k, v in ff.levels_m.items()))
    return 0


def _target_model(bodies: bool) -> str:
    """How a far-field target was modelled (for the summary)."""
    return (
        "body (coverage.body), heading along the lane"
        if bodies
        else "point at the target's reference height (the paper's setting)"
    )


def cmd_paper(args: argparse.Namespace) -> int:
    """Reproduce the paper's results section into --out."""
    from sensorgap.analysis.paper import run_paper

    _refuse_unsafe_out(args.out, "paper")
    with removed_on_error(args.out):  # a failed paper leaves no partial output
        result = run_paper(Path(args.out))
        write_manifest(args.out)
    for name, ok in result["checks"].items():
        print(f"[{'ok' if ok else 'FAIL'}] {name}")
    print(
        "sensitivity of Table IV to the calibrated parameters (sensitivity.csv): "
        "agreement shows the model can reproduce the paper, not that it predicts it"
    )
    for r in result["sensitivity"]:
        print(
            f"  {r['parameter']} = {r['value']:g} {r['unit']}: largest change "
            f"{r['max_change_m']:+.0f} m ({r['cell']}), blind spots "
            f"{r['nearfield_change_m2']:+.2f} m2"
        )
    return 0


def cmd_search(args: argparse.Namespace) -> int:
    """Search for critical scenarios into --out (SQLite store, ranking.csv/json)."""
    from sensorgap.search.ranking import RANK_MIN_P
    from sensorgap.search.run import run_search
    from sensorgap.steps import certified_search

    env_file = Path(args.environments_file) if args.environments_file else None
    outcome, gone = certified_search(
        Path(args.out),
        args.resume,
        lambda stop: run_search(
            args.vehicle,
            _families(args.families),
            _environments(args.environments, env_file),
            args.budget,
            args.seed,
            args.top,
            Path(args.out),
            strategy=args.strategy,
            mode=args.pd,
            sun_search=not args.no_sun,
            environments_file=env_file,
            detection=args.detection,
            workers=args.workers,
            resume=args.resume,
            executor=args.executor,
            scheduler=args.scheduler,
            seeds=args.seeds,
            stop=stop,
        ),
    )
    if gone:
        print(
            f"the resumed search changed the ranking: removed {len(gone)} files of the "
            "previous export and report (run export and report again)"
        )
    crit = sum(1 for r in outcome.ranking if r["class"] == "sensor-critical")
    d = outcome.summary["lookup_vs_exact"]
    if args.pd == "lookup" and d.get("reevaluated"):
        print(
            f"lookup vs exact over the {d['reevaluated']} best candidates (re-evaluated "
            f"exactly; every reported number is exact): mean |dP_collision| "
            f"{d['mean_abs_diff_collision_probability']:.3g}, max "
            f"{d['max_abs_diff_collision_probability']:.3g}; sensor-critical at any "
            f"P(collision) > 0: {d['sensor_critical_lookup']} by lookup, "
            f"{d['sensor_critical_exact']} exactly, {d['sensor_critical_both']} both (the "
            f"ranking keeps those at {RANK_MIN_P:g} or more, near-duplicates merged)"
        )
    found = (
        outcome.summary["note"]  # none feasible: "best collision probability 0" read as safe
        if "note" in outcome.summary
        else f"best collision probability {outcome.summary['best_collision_probability']:.3g}"
    )
    print(
        f"{args.out}: {outcome.evaluated} evaluated, {outcome.reused} reused, "
        f"{len(outcome.ranking)} ranked ({crit} sensor-critical)"
        f"{'; ' if 'note' in outcome.summary else ', '}{found}"
    )
    return 0


def _name_list(text: str, option: str) -> list[str]:
    """A comma-separated list of names, each stripped; an empty item (a trailing comma,
    two commas together) is refused, not skipped: it is a name the user meant to type."""
    names = [n.strip() for n in text.split(",")]
    if len(names) > 1 and not all(names):
        raise InputError(
            option,
            "",
            f"an empty name in {text!r} (a comma with no name after it); "
            "give names separated by single commas",
        )
    return [n for n in names if n]


def _families(text: str) -> list[str]:
    """``all`` or a comma-separated list of family names / .toml paths."""
    from sensorgap.scenarios import family_presets

    if text.strip() == "all":
        return family_presets()
    return _name_list(text, "--families")


def _environments(text: str, env_file: Path | None) -> list[str]:
    """``all`` (every preset of the environments file) or a comma-separated list."""
    from sensorgap.config import load_environments

    if text.strip() == "all":
        return list(load_environments(env_file))
    return _name_list(text, "--environments")


def cmd_evaluate(args: argparse.Namespace) -> int:
    """Evaluate one candidate exactly into --out (evaluation.json, trace.csv)."""
    from sensorgap.config.parameters import bound_error
    from sensorgap.search.whatif import evaluate_candidate, parse_sun

    for item in args.param or []:  # physical bounds (config.parameters), before any work
        name, _, text = item.partition("=")
        try:
            why = bound_error(name, parse_decimal(text))
        except ValueError:
            why = None  # not a number: parse_params names it
        if why:
            raise InputError("param", name, why)
    # the ranking's environment label, NAME@sunAZ/EL, as NAME with --sun AZ/EL (a preset
    # name holds no '@'); given both ways, they must agree
    environment, at, sun = str(args.environment).partition("@sun")
    if at and args.sun is not None and args.sun != sun:
        raise InputError(
            "--environment",
            "",
            f"{args.environment!r} gives the sun as {sun!r}, --sun as {args.sun!r}: give it once",
        )
    sun = sun if at else args.sun
    # files no manifest lists: a certified folder (a search run) would fail its verify
    refuse_certified_out(args.out, "evaluate")
    try:
        # a failed evaluation leaves neither of its files nor a folder it made
        with removed_on_error(args.out, only=("evaluation.json", "trace.csv")):
            ev = evaluate_candidate(
                args.vehicle,
                args.family,
                environment,
                parse_sun(sun),
                args.param or [],
                Path(args.out),
                Path(args.environments_file) if args.environments_file else None,
                Path(args.run) if args.run else None,
            )
    except InputError as exc:
        if exc.source == "families":  # the family loader names search's --families
            exc.source = "--family"
        if exc.source == "sun" and at:  # the sun was written into --environment (round 29)
            raise InputError("--environment", exc.field, f"{exc.message} (its @sun part)") from None
        raise
    m = ev["metrics"]
    if not ev["feasible"]:
        print(f"{args.out}: infeasible: {ev['note']}")
    else:
        print(
            f"{args.out}: {ev['class']}, P(collision) {m['collision_probability']:.3g}, "
            f"impact {m['impact_speed_kmh']:.1f} km/h"
        )
    return 0


#: The file by which each command with many outputs knows its own earlier ``--out`` (its
#: manifest lists it; ``_refuse_unsafe_out``): ``compare`` and ``report --compare`` write
#: the same files (``report.compare.write_compare_report``), so each takes the other's.
OWN_OUTPUT = {
    "paper": "paper.md",
    "tradeoff": "tradeoff.csv",
    "compare": "comparison.json",
    "report --compare": "comparison.json",
}


def _refuse_unsafe_out(out: str | Path, command: str) -> None:
    """``--out`` of a command with many outputs that then certifies the whole folder
    (``paper``, ``tradeoff``, ``compare``, ``report --compare``, ``run``): not a search run
    or catalog (it would add to and re-certify it, overwriting e.g. its report), no
    certified file changed by hand since (the new manifest would certify it), and not
    another command's certified output (``OWN_OUTPUT``: its manifest lists no file of this
    command's; a near-field or coverage folder was accepted, the mix certified). Its own
    earlier output is accepted (a rerun); ``run`` checks its own kind of folder
    (``cmd_run``)."""
    refuse_foreign_outputs(out, None, command)
    refuse_if_changed(out, ())
    own = OWN_OUTPUT.get(command)
    if own is not None:
        refuse_certified_by_other(out, command, lambda rel: rel == own, own)
    refuse_inside_certified(out, command)


def _out_outside(out: Path, *runs: Path) -> None:
    """``--out`` of a comparison must not be a run folder or lie inside one (it would add
    files to a certified folder, which ``verify`` then reports)."""
    where = out.resolve()
    for run in runs:
        r = run.resolve()
        if where == r or r in where.parents:
            raise InputError(
                "--out",
                "",
                f"must be outside the run folders compared; {out} is inside {run}",
            )


def cmd_compare(args: argparse.Namespace) -> int:
    """Two vehicles side by side (A vs B), complete: what either run lacks (near field,
    coverage maps, far field) is computed from its recorded inputs; the coverage difference
    maps; the cross-evaluation of both runs' critical scenarios; report.html/.md."""
    from sensorgap.report.compare import write_compare_report
    from sensorgap.search.compare import check_rankings

    # both must be search runs with readable rankings: refused before anything is written
    check_rankings(Path(args.run_a), Path(args.run_b))
    _out_outside(Path(args.out), Path(args.run_a), Path(args.run_b))
    _refuse_unsafe_out(args.out, "compare")
    with removed_on_error(args.out):
        html_path, _ = write_compare_report(Path(args.run_a), Path(args.run_b), Path(args.out))
        write_manifest(args.out)
    data = json.loads((Path(args.out) / "comparison.json").read_text(encoding="utf-8"))
    rows = data["rows"]
    who = sorted({str(r["critical_for"]) for r in rows})
    print(
        f"{args.out}: {len(rows)} scenarios compared; critical for: {', '.join(who) or 'none'}; "
        f"maps, difference maps and report: {html_path}"
    )
    for note in data.get("run_notes", []):
        print(f"note of run {note}")
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    """OpenSCENARIO + OpenDRIVE catalog of a search run's ranked scenarios."""
    from sensorgap.steps import certified_export

    out = Path(args.out) if args.out else None
    index, gone = certified_export(Path(args.run), out, args.osc_version, args.top, args.style)
    if gone:
        print(
            f"the export changed the scenario files: removed {len(gone)} files of "
            "the previous report (run report again)"
        )
    print(
        f"{out or args.run}: {len(index['scenarios'])} scenarios, {args.style} style, "
        f"OpenSCENARIO {args.osc_version}, every file XSD-valid"
    )
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    """Run a catalog's scenarios in esmini; simulation.csv."""
    from sensorgap.export.simulate import WALL_KEY, simulate_catalog

    refuse_if_changed(args.catalog, ("simulation.csv",))  # its manifest is rewritten
    # a failed run leaves the catalog as it was (simulation.csv and its manifest entry)
    # locked before any work when it exists (_written_folders); a missing one is refused
    with removed_on_error(
        args.catalog, only=("simulation.csv", "manifest.json"), lock=False, certifies=True
    ):
        rows = simulate_catalog(
            Path(args.catalog),
            args.esmini,
            timeout_s=args.timeout,
            step_s=args.step,
            ego_reaction=args.ego_reaction,
        )
        write_manifest(args.catalog, ("simulation.csv",))
    ok = sum(1 for r in rows if r.get("status") == "ok")
    within = sum(1 for r in rows if r.get("within_0p5m") == "yes")
    coll = sum(1 for r in rows if r.get("collision_agrees") == "yes")
    trig = [r for r in rows if r.get("trigger_agrees")]
    trig_ok = sum(1 for r in trig if r["trigger_agrees"] == "yes")
    triggers = (
        f", {trig_ok}/{len(trig)} with their relative triggers within 0.1 s / 0.5 m of the plan"
        if trig
        else ""
    )
    wall = sum(float(r.get(WALL_KEY, 0.0)) for r in rows)
    print(
        f"{args.catalog}: {ok}/{len(rows)} ran cleanly to the end, {within} within 0.5 m "
        f"of the plan, {coll} with the plan's collision outcome (esmini --collision)"
        f"{triggers}; esmini ran {wall:.1f} s in all"
    )
    if args.ego_reaction:
        runs = [
            r[k]
            for r in rows
            for k in r
            if k.startswith("react_") and k.endswith("_agrees") and r[k]
        ]
        tol = [
            r[k]
            for r in rows
            for k in r
            if k.startswith("react_") and k.endswith("_within_plan") and r[k]
        ]
        same = sum(
            1
            for r in rows
            for q in ("median", "p90")
            if r.get(f"react_{q}_agrees") == "yes"
            and r.get(f"react_{q}_collision_predicted_s", "") != ""
            and r.get(f"react_{q}_collision_esmini_s", "") != ""
            and abs(
                float(r[f"react_{q}_collision_predicted_s"])
                - float(r[f"react_{q}_collision_esmini_s"])
            )
            <= args.step + 1e-9
        )
        hits = sum(
            1
            for r in rows
            for q in ("median", "p90")
            if r.get(f"react_{q}_agrees") == "yes"
            and r.get(f"react_{q}_collision_predicted_s", "") != ""
        )
        print(
            f"  ego reaction (brake at the median / 90th-percentile confirmation): "
            f"{runs.count('yes')}/{len(runs)} runs agree with the reaction model's "
            f"prediction (collision or not, impact speed within 2 km/h); {same}/{hits} "
            "of the agreeing collisions at the predicted step (one step); "
            f"{tol.count('yes')}/{len(tol)} within the plan's tolerance (impact speeds "
            "whose braking distances differ by at most the 0.5 m to which esmini's ego "
            "follows the plan)"
        )
    for r in rows:
        if r.get("status") != "ok":
            print(f"  {r['scenario_id']}: {r['status']}: {r.get('message', '')}")
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    """The audit report of a run folder, or two runs side by side."""
    if args.compare and args.run:  # one of them would be ignored
        raise InputError("--run", "", "give --run DIR or --compare RUN_A RUN_B, not both")
    if args.compare:
        from sensorgap.report.compare import write_compare_report
        from sensorgap.search.compare import check_rankings

        a, b = (Path(p) for p in args.compare)
        out = Path(args.out) if args.out else a.parent / f"compare_{a.name}_vs_{b.name}"
        check_rankings(a, b)  # both search runs: refused before anything is written
        _out_outside(out, a, b)
        _refuse_unsafe_out(out, "report --compare")
        with removed_on_error(out):  # a failed comparison leaves no partial output
            html_path, md_path = write_compare_report(a, b, out)
            write_manifest(out)
    else:
        if not args.run:
            raise InputError("--run", "", "give --run DIR or --compare RUN_A RUN_B")
        if args.out:  # it would be ignored: the report of a run goes into the run
            raise InputError(
                "--out", "", "only with --compare (the report of --run is written into the run)"
            )
        from sensorgap.steps import certified_report

        html_path, md_path = certified_report(Path(args.run))
    print(f"{html_path} and {md_path}")
    return 0


def _refuse_locked(folder: Path) -> None:
    """``verify`` of a folder another sensorgap command is writing now (it holds the
    folder's lock, ``locks.locked_elsewhere``): its files are half-written and its
    restore folder is in use, not left over from a killed command. ``InputError``."""
    from sensorgap.locks import locked_elsewhere

    if locked_elsewhere(folder):
        raise InputError(
            folder,
            "",
            "being written by another sensorgap command now (its lock is held); verify it "
            "when that command ends",
        )


def cmd_verify(args: argparse.Namespace) -> int:
    """Check a run folder against its manifest (nothing lost or changed)."""
    from sensorgap.filesio import verify_manifest
    from sensorgap.search.runfolder import check_recorded, search_runs

    if not str(args.folder).strip():  # '' would verify the working directory
        raise InputError(
            "verify",
            "FOLDER",
            f"must name a run folder (an empty path is the working directory), got {args.folder!r}",
        )
    folder = Path(args.folder)
    manifest = folder / "manifest.json"
    if not folder.is_dir():
        raise InputError(
            folder,
            "",
            "is not a folder: give a run folder"
            if os.path.lexists(folder)
            else "folder does not exist",
        )
    if manifest.is_symlink() or not manifest.is_file():
        _refuse_locked(folder)  # a run being made has no manifest yet (hostile round 41)
        raise InputError(manifest, "", "no manifest in this folder (not a sensorgap run)")
    _refuse_locked(folder)  # a command writing it: its restore folder is no left-over
    problems = verify_manifest(folder)
    if problems:
        _refuse_locked(folder)  # a command that started while it was checked
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise InputError(manifest, "files", f"{problems[0]}{more}")
    try:  # the recorded inputs as export and report read them
        check_recorded(folder)
    except InputError:
        _refuse_locked(folder)
        raise
    print(
        f"{folder}: every file of the manifest is present and unchanged"
        + (", and every recorded input matches run.json" if search_runs(folder) else "")
    )
    return 0


def cmd_tradeoff(args: argparse.Namespace) -> int:
    """Measure speed against accuracy of every approximation."""
    from sensorgap.tradeoff import run_tradeoff

    _refuse_unsafe_out(args.out, "tradeoff")
    with removed_on_error(args.out):
        rows = run_tradeoff(Path(args.out), quick=args.quick)
    print(f"{args.out}: {len(rows)} measurements (tradeoff.csv, tradeoff.md, resolution.png)")
    return 0


def cmd_corridor(args: argparse.Namespace) -> int:
    """The least-detectable approach path into a critical zone (corridor search)."""
    from sensorgap.search.corridor import corridor_search

    refuse_foreign_outputs(args.out, ANALYSIS_WRITES["corridor"], "corridor", _COMMAND_FILES)
    refuse_inside_certified(args.out, "corridor")
    lanes = []
    for part in args.lanes.split(","):
        bits = part.split(":")
        try:
            lo_hi = [parse_decimal(b) for b in bits]
        except ValueError:
            lo_hi = []
        if len(lo_hi) != 2 or not all(math.isfinite(v) for v in lo_hi):
            raise InputError(
                "--lanes",
                "",
                "expected bands LO:HI of finite numbers (m), comma-separated, e.g. "
                f"-7.5:-3.75,-3.75:0; got {part!r} in {args.lanes!r}",
            )
        lanes.append((lo_hi[0], lo_hi[1]))
    res = _positive(args.lateral_res, "--lateral-res")
    for opt, v in (("--start", args.start), ("--goal", args.goal), ("--speed", args.speed)):
        if not math.isfinite(v):
            raise InputError(opt, "", f"must be a finite number, got {v!r}")
    scene = _scene(args)
    try:
        c = corridor_search(scene, args.start, args.goal, lanes, args.speed, lateral_res=res)
    except InputError as exc:  # name the options of this command
        flag = {
            "x_start/x_goal": "--start/--goal",
            "lanes": "--lanes",
            "lateral_res": "--lateral-res",
            "speed_rel": "--speed",
        }.get(exc.field)
        if exc.source == "corridor" and flag:
            raise InputError(flag, "", exc.message) from None
        raise
    out = Path(args.out)
    with removed_on_error(out):
        _write_corridor(args, scene, c, lanes, res, out)
    print(
        f"{out}: P(undetected along the corridor) = {c.p_undetected:.3g} "
        f"(log10 {c.log10_p_undetected:.1f}) over {c.t[-1]:.1f} s"
    )
    return 0


def _write_corridor(
    args: argparse.Namespace,
    scene: Scene,
    c: Any,
    lanes: list[tuple[float, float]],
    res: float,
    out: Path,
) -> None:
    from sensorgap.coverage import GridSpec, evaluate_grid
    from sensorgap.coverage.plot import coverage_figure, save_figure
    from sensorgap.filesio import write_csv, write_json

    out.mkdir(parents=True, exist_ok=True)
    write_csv(
        out / "corridor.csv", ["t", "x", "y", "heading", "pd"], [c.t, c.x, c.y, c.heading, c.pd]
    )
    ys = [lo for lo, _ in lanes] + [hi for _, hi in lanes]
    x0, x1 = min(args.start, -10.0) - 5.0, max(args.goal, 10.0) + 5.0
    y0, y1 = min(ys) - 10.0, max(ys) + 10.0
    plot_res = max(0.25, math.sqrt((x1 - x0) * (y1 - y0) / 4e6))  # background <= 4e6 cells
    grid = GridSpec(x0, x1, y0, y1, plot_res, scene.target.reference_height_m)
    fig = coverage_figure(
        evaluate_grid(scene, grid, workers=2),
        scene.system,
        f"{scene.system.name}: least-detectable {scene.target.name} path, "
        f"{scene.conditions.env.name}, P_undet = {c.p_undetected:.3g}",
    )
    fig.axes[0].plot(c.x, c.y, color="magenta", linewidth=2.0, label="corridor")
    fig.axes[0].legend(loc="upper left", fontsize=8)
    save_figure(fig, out / "corridor.png")
    write_json(
        out / "summary.json",
        {
            "vehicle": scene.system.name,
            "environment": scene.conditions.env.name,
            "target": scene.target.name,
            "start_x_m": args.start,
            "goal_x_m": args.goal,
            "lanes_m": lanes,
            "speed_rel_m_s": args.speed,
            "lateral_res_m": res,
            "p_undetected": c.p_undetected,
            "log10_p_undetected": c.log10_p_undetected,
            "duration_s": float(c.t[-1]),
            "min_pd": float(c.pd.min()),
            "max_pd": float(c.pd.max()),
            "files": ["corridor.csv", "corridor.png", "summary.json"],
        },
    )
    write_manifest(out)


def cmd_schema(args: argparse.Namespace) -> int:
    """Print the JSON Schema of vehicle / environment / target files."""
    from sensorgap.filesio import json_bytes
    from sensorgap.models.schema import file_schemas

    schemas = file_schemas()
    out = schemas if args.kind == "all" else schemas[args.kind]
    sys.stdout.write(json_bytes(out).decode("utf-8"))
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    """The default main job into --out."""
    from sensorgap.jobs import run_default

    if not 1 <= args.workers <= 64:
        raise InputError("--workers", "", f"must be 1..64, got {args.workers}")
    from sensorgap.search.settings import MAX_BUDGET

    if not 1 <= args.budget <= MAX_BUDGET:  # the search's own limit, said before any work
        raise InputError("--budget", "", f"must be within 1..{MAX_BUDGET}, got {args.budget}")
    if not 0 <= args.seed < 2**63:
        raise InputError("--seed", "", f"must be a non-negative integer, got {args.seed}")
    from sensorgap.scenarios import load_families

    families = _families(args.families)
    load_families(families)  # every family (and its road) checked before any work
    _refuse_unsafe_out(args.out, "run")
    # OUT of an earlier job (its manifest lists <vehicle>/manifest.json), not another
    # command's certified output (a coverage folder)
    refuse_certified_by_other(
        args.out,
        "run",
        lambda rel: rel.count("/") == 1 and rel.endswith(f"/{MANIFEST_NAME}"),
        f"<vehicle>/{MANIFEST_NAME} of a job",
    )
    run_default(
        Path(args.out),
        workers=args.workers,
        system_name=args.vehicle,
        budget=args.budget,
        seed=args.seed,
        families=families,
        environments=_environments(args.environments, None),
        seeds=args.seeds,
        certify_out=True,
    )
    return 0


def _add_scene_args(p: argparse.ArgumentParser) -> None:
    p.add_argument("--vehicle", required=True, help="preset name (system_a) or .toml path")
    p.add_argument("--environment", required=True, help="environment preset name")
    p.add_argument(
        "--environments-file",
        help="environments file defining the presets (default: the shipped ones)",
    )
    p.add_argument("--target", required=True, help="pedestrian | bike | car | truck")


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit code 2)."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_INPUT, f"{self.prog}: error: {clip(message)} (see --help)\n")

    def print_help(self, file: SupportsWrite[str] | None = None) -> None:
        """``--help`` onto standard output through ``guarded_stdout`` (hostile round
        eleven, F9: with stdout closed argparse printed it on stderr, into a full device
        it was lost; both exited 0): ``StdoutUnwritable`` when it cannot be written."""
        if file is not None:
            super().print_help(file)
            return
        with guarded_stdout():
            super().print_help(sys.stdout)


class _DefaultsFormatter(argparse.ArgumentDefaultsHelpFormatter):
    """Shows every default, except where the help already says what it is."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        if "(default:" in text:
            return text
        return super()._get_help_string(action)


class _HelpParser(_Parser):
    """A subcommand's parser: one-line errors, and every default shown in ``--help``."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", _DefaultsFormatter)
        super().__init__(*args, **kwargs)


def _budget_options(
    p: argparse.ArgumentParser,
    budget: tuple[int, str],
    seed: tuple[int, str],
    seeds: tuple[int, str],
) -> None:
    """``--budget``, ``--seed`` and ``--seeds`` of a searching command: (default, help)."""
    for flag, (default, text) in (("--budget", budget), ("--seed", seed), ("--seeds", seeds)):
        p.add_argument(flag, type=_integer, default=default, help=text)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``sensorgap`` command."""
    parser = _Parser(prog="sensorgap", description=__doc__)
    parser.add_argument("--debug", action="store_true", help="show tracebacks")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_HelpParser)

    p = sub.add_parser("probe", help="SNR and Pd per sensor at points from a CSV")
    _add_scene_args(p)
    p.add_argument("--points", required=True, help="CSV with columns x,y[,z] (vehicle frame, m)")
    p.add_argument(
        "--heading",
        type=_decimal,
        default=None,
        help="evaluate target bodies centred at the points at this heading "
        "relative to the ego, deg (default: points)",
    )
    p.add_argument("--out", help="output CSV (default: stdout)")
    p.set_defaults(func=cmd_probe)

    p = sub.add_parser("coverage", help="coverage grid, heat map and summary")
    _add_scene_args(p)
    p.add_argument("--height", type=_decimal, help="m (default: the target's reference height)")
    p.add_argument("--resolution", type=_decimal, default=0.5, help="cell size, m")
    p.add_argument("--extent", default="-60,160,-40,40", help="XMIN,XMAX,YMIN,YMAX in m")
    p.add_argument("--per-sensor", action="store_true", help="also store each sensor's map")
    p.add_argument(
        "--heading",
        type=_decimal,
        default=None,
        help="target bodies centred at the cells at this heading relative to the "
        "ego, deg (default: points at --height)",
    )
    p.add_argument(
        "--occluder",
        action="append",
        default=[],
        metavar="KIND@X,Y,HEADING",
        help="a road user standing still as an occluder (a target class of "
        "targets.toml sized box, centre X,Y m in the vehicle frame, HEADING deg "
        "relative to the ego); repeatable; needs --heading (target bodies)",
    )
    p.add_argument("--workers", type=_integer, default=2, help="threads")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_coverage)

    p = sub.add_parser("nearfield", help="near-field blind spots (Fig. 5)")
    p.add_argument("--vehicle", required=True, help="preset name or .toml path")
    p.add_argument("--resolution", type=_decimal, default=0.05, help="grid cell size, m")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_nearfield)

    p = sub.add_parser("farfield", help="Pd along a lane ahead of the ego (Table IV)")
    p.add_argument("--vehicle", required=True, help="preset name or .toml path")
    p.add_argument("--environment", required=True, help="environment preset name")
    p.add_argument("--road", default="motorway_r500", help="road name or .xodr path")
    p.add_argument("--road-id", default="1", help="OpenDRIVE road id")
    p.add_argument("--ego-lane", type=_integer, default=-1, help="ego lane id")
    p.add_argument("--ego-s", type=_decimal, default=450.0, help="ego position along the road, m")
    p.add_argument("--target-lane", type=_integer, default=-2, help="target lane id")
    p.add_argument("--target", default="car", help="pedestrian | bike | car | truck")
    p.add_argument("--length", type=_decimal, default=303.0, help="path length ahead, m")
    p.add_argument(
        "--target-model",
        choices=("body", "point"),
        default="body",
        help="the target as its body heading along the lane, or as a point at "
        "its reference height (the paper's setting)",
    )
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_farfield)

    p = sub.add_parser("paper", help="reproduce the paper's near-field areas and Table IV")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_paper)

    p = sub.add_parser("search", help="search for critical scenarios (undetected and dangerous)")
    p.add_argument("--vehicle", required=True, help="preset name or .toml path")
    p.add_argument(
        "--families",
        default="all",
        help="'all' (every family of templates/scenarios) or comma-separated "
        "family names or .toml paths",
    )
    p.add_argument(
        "--environments",
        default="all",
        help="'all' (every preset) or comma-separated environment presets",
    )
    p.add_argument(
        "--environments-file",
        help="environments file defining the presets (default: the shipped ones)",
    )
    _budget_options(
        p,
        (200, "evaluations in total"),
        (0, "random seed"),
        (
            1,
            "run the budget as this many independent searches (1..10) and "
            "say per ranked row how many found it (the ranking's stability)",
        ),
    )
    p.add_argument("--top", type=_integer, default=10, help="ranked scenarios to write")
    p.add_argument("--strategy", default="de", help="de | cem | lhs | random | grid (or a plugin)")
    p.add_argument(
        "--pd",
        default="lookup",
        choices=["lookup", "exact"],
        help="Pd per step from cached coverage maps or exact evaluation",
    )
    p.add_argument("--no-sun", action="store_true", help="do not search sun azimuth/elevation")
    p.add_argument(
        "--detection",
        default="cumulative",
        help="reliable detection: 'cumulative' (Pd >= 0.99) or M/N confirmation",
    )
    p.add_argument(
        "--workers", type=_integer, default=2, help="threads per batch, or Dask worker processes"
    )
    p.add_argument(
        "--executor",
        default="local",
        choices=["local", "dask"],
        help="evaluate batches here (threads) or on Dask distributed",
    )
    p.add_argument("--scheduler", help="Dask scheduler address (default: a local cluster)")
    p.add_argument(
        "--resume", action="store_true", help="continue the search stored in --out (same settings)"
    )
    p.add_argument("--out", required=True, help="run folder")
    p.set_defaults(func=cmd_search)

    p = sub.add_parser("evaluate", help="one candidate, exact: metrics and a per-step trace")
    p.add_argument("--vehicle", help="preset name or .toml path (or give --run)")
    p.add_argument(
        "--run",
        help="search run folder: use the vehicle, environments, "
        "families, targets and reaction model it recorded",
    )
    p.add_argument("--family", required=True, help="family name or .toml path")
    p.add_argument(
        "--environment",
        required=True,
        help="environment preset, or a ranking's label NAME@sunAZ/EL (NAME with --sun AZ/EL)",
    )
    p.add_argument("--environments-file", help="environments file (default: shipped presets)")
    p.add_argument("--sun", help="AZ/EL: world-frame sun, deg (default: the preset's)")
    p.add_argument(
        "--param",
        action="append",
        metavar="NAME=VALUE",
        help="a family parameter (repeat for each)",
    )
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_evaluate)

    p = sub.add_parser("export", help="OpenSCENARIO + OpenDRIVE catalog of a search run")
    p.add_argument("--run", required=True, help="search run folder (ranking.json)")
    p.add_argument("--out", help="catalog folder (default: the run folder)")
    p.add_argument(
        "--osc-version",
        default="1.2",
        choices=["1.0", "1.1", "1.2", "1.3"],
        help="OpenSCENARIO version",
    )
    p.add_argument("--top", type=_integer, help="export only the first N ranked scenarios")
    p.add_argument(
        "--style",
        default="maneuver",
        choices=["maneuver", "replay"],
        help="maneuver: actions started relative to the ego, for a system under "
        "test (default); replay: the evaluated paths as timed polylines",
    )
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("simulate", help="run a catalog in esmini and compare the paths")
    p.add_argument("--catalog", required=True, help="catalog folder (catalog.json)")
    p.add_argument("--esmini", help="esmini executable (default: $SENSORGAP_ESMINI or PATH)")
    p.add_argument("--timeout", type=_decimal, default=60.0, help="hard limit per scenario, s")
    p.add_argument("--step", type=_decimal, default=0.05, help="fixed simulation step, s")
    p.add_argument(
        "--ego-reaction",
        action="store_true",
        help="also run each scenario with the ego braking at the median and "
        "90th-percentile confirmation time (reaction model) and compare esmini's "
        "collision and impact speed with the prediction",
    )
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("report", help="audit report (report.html + report.md) of a run")
    p.add_argument("--run", help="run folder (make run: output/system_a)")
    p.add_argument(
        "--compare", nargs=2, metavar=("RUN_A", "RUN_B"), help="two run folders side by side"
    )
    p.add_argument("--out", help="output folder of --compare (default: beside RUN_A)")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("tradeoff", help="measure speed against accuracy (grid, lookup, scope)")
    p.add_argument("--out", required=True, help="output folder")
    p.add_argument("--quick", action="store_true", help="coarse settings (seconds)")
    p.set_defaults(func=cmd_tradeoff)

    p = sub.add_parser("verify", help="check a run folder against its manifest.json")
    p.add_argument("folder", help="run or catalog folder")
    p.set_defaults(func=cmd_verify)

    p = sub.add_parser(
        "compare",
        help="two vehicles side by side: maps, difference maps, "
        "cross-evaluated critical scenarios, report (A vs B)",
    )
    p.add_argument("run_a", help="search run folder of the first vehicle")
    p.add_argument("run_b", help="search run folder of the second vehicle")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("corridor", help="least-detectable approach path (corridor search)")
    _add_scene_args(p)
    p.add_argument("--start", type=_decimal, default=-60.0, help="start x (vehicle frame), m")
    p.add_argument("--goal", type=_decimal, default=6.0, help="critical-zone x, m")
    p.add_argument(
        "--lanes",
        default="-7.5:-3.75",
        help="lateral lane bands LO:HI[,LO:HI...] in the vehicle frame, m",
    )
    p.add_argument("--speed", type=_decimal, default=8.0, help="relative speed along x, m/s")
    p.add_argument("--lateral-res", type=_decimal, default=0.25, help="lattice row spacing, m")
    p.add_argument("--out", required=True, help="output folder")
    p.set_defaults(func=cmd_corridor)

    p = sub.add_parser("schema", help="JSON Schema of the config files")
    p.add_argument(
        "kind", nargs="?", default="all", choices=["all", "vehicle", "environments", "targets"]
    )
    p.set_defaults(func=cmd_schema)

    p = sub.add_parser(
        "run",
        help="the main job for a vehicle: coverage, near field, far "
        "field, search, export, report into OUT/<vehicle>/",
    )
    p.add_argument("--vehicle", default="system_a", help="preset name or .toml path")
    p.add_argument("--out", default="output", help="output folder")
    _budget_options(
        p,
        (100_000, "search evaluations in total"),
        (1, "random seed of the search"),
        (
            3,
            "the budget as this many independent searches (1..10): the report "
            "says how many found each top weakness",
        ),
    )
    p.add_argument(
        "--families", default="all", help="'all' or comma-separated family names or .toml paths"
    )
    p.add_argument(
        "--environments", default="all", help="'all' or comma-separated environment presets"
    )
    p.add_argument("--workers", type=_integer, default=2, help="threads")
    p.set_defaults(func=cmd_run)
    return parser


def _flag_sources(exc: InputError, parser: argparse.ArgumentParser, command: str) -> None:
    """Name CLI options where the library names arguments: an error whose source is an
    option's destination (``environments_file``) is reported as the option
    (``--environments-file``) when ``command`` has that option; files, fields and the
    arguments of a command without such an option stay as they are (hostile round 28:
    ``tradeoff`` named ``--environment``, another command's option)."""
    flags: dict[str, str] = {}
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction) and command in action.choices:
            for a in action.choices[command]._actions:
                if a.option_strings and a.dest not in flags:
                    flags[a.dest] = max(a.option_strings, key=len)
    for e in (exc, *exc.more):
        if e.source in flags:
            e.source = flags[e.source]


def _written_folders(args: argparse.Namespace) -> list[Path]:
    """The existing folders the command of ``args`` writes into (``--out``; ``export``
    in place and ``report --run``: ``--run``; ``simulate``: ``--catalog``), locked for
    its whole run before any work (``locks.folder_lock``). None for the readers
    (``verify``, ``schema``) and ``probe`` (one file renamed into a user's folder)."""
    func = getattr(args, "func", None)
    if func in (cmd_verify, cmd_schema, cmd_probe):
        return []
    if func is cmd_simulate:
        paths = [args.catalog]
    elif func is cmd_export:
        paths = [args.out or args.run]
    elif func is cmd_report:
        paths = [args.out] if args.compare else [args.run]
    else:
        paths = [getattr(args, "out", None)]
    return [Path(p) for p in paths if isinstance(p, str) and os.path.isdir(p)]


def _new_report_inputs(args: argparse.Namespace) -> list[Path]:
    """A new ``--out`` of ``nearfield`` or ``coverage`` that is a search run's report
    input (``filesio.certified_parent``: ``RUN/nearfield``, ``RUN/coverage/<name>``): not
    locked itself (it does not exist yet), but its run is (``_lock_job_out``)."""
    out = getattr(args, "out", None)
    if args.command not in ("nearfield", "coverage") or not isinstance(out, str):
        return []
    return [] if os.path.lexists(out) else [Path(out)]


def _lock_job_out(folder: Path, locks: ExitStack, command: str | None) -> None:
    """When ``folder`` lies in a certified folder the command certifies again
    (``filesio.certified_parent``: ``OUT/<vehicle>`` of a job, ``RUN/nearfield``), hold
    that folder too, and its own such parent (``OUT/<vehicle>/nearfield``: the vehicle
    folder and OUT): locked (no ``run`` into it meanwhile), its other files checked as
    certified (``refuse_if_changed``), and its ``manifest.json`` kept, put back if the
    command fails; the command's ``write_manifest`` certifies each again."""
    from sensorgap.filesio import certified_parent

    found = certified_parent(folder, command)
    while found is not None:
        parent, rel = found
        locks.enter_context(folder_lock(parent))
        refuse_if_changed(parent, (f"{rel}/",))
        locks.enter_context(
            removed_on_error(parent, only=(MANIFEST_NAME,), lock=False, certifies=True)
        )
        found = certified_parent(parent)


def _remove_fresh(path: Path | None) -> str:
    """Remove ``path``, an ``--out`` that did not exist when the command started (its
    standard output failed after it wrote there: a failed command leaves nothing); the
    clause saying so, '' when there was nothing to remove. An --out that existed is
    left alone (a run folder with its manifest)."""
    if path is None or not os.path.lexists(path):
        return ""
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with suppress(OSError):
            path.unlink()
    return f" and removed {path}, which it had written" if not os.path.lexists(path) else ""


def _check_environment() -> None:
    """The process's environment, checked before any command starts (one line, exit 2):
    the working directory still exists (numba imports coverage.py, which resolves it:
    every computing command failed with "output: cannot write or read: No such file or
    directory"), ``SOURCE_DATE_EPOCH`` (``provenance.source_date_epoch``: numpy's f2py,
    imported by numba, read it with ``int()`` and ``time.gmtime``: internal errors) and
    ``SENSORGAP_TEMPLATES`` (``config.presets.templates_dir``), ``SENSORGAP_ROADS``
    (``roads_dir``), ``SENSORGAP_ESMINI`` (an executable file) and numba's ``NUMBA_*`` variables
    (``runtime.check_numba_environment``)."""
    from sensorgap.config.presets import roads_dir, templates_dir
    from sensorgap.provenance import source_date_epoch

    try:
        os.getcwd()
    except OSError as exc:
        why = (
            "no longer exists (it was deleted or moved after the shell entered it)"
            if isinstance(exc, FileNotFoundError)
            else f"cannot be read ({exc.strerror})"
        )
        raise InputError(
            "working directory", "", f"{why}; change into an existing folder and run again"
        ) from None
    source_date_epoch()
    templates_dir()
    roads_dir()
    esmini = os.environ.get("SENSORGAP_ESMINI")
    if esmini and not (os.path.isfile(esmini) and os.access(esmini, os.X_OK)):
        shown = esmini if esmini.strip() == esmini else repr(esmini)
        raise InputError(
            "SENSORGAP_ESMINI",
            "",
            f"{shown} is not an executable file; it must name the esmini program, or not be set",
        )
    check_numba_environment()


def _os_error_line(exc: OSError, out: object) -> str:
    """The one line of a failed file operation: the file named (a full disk's copy names
    its destination, ``filename2``; a failed write names no file: ``--out``), the
    system's reason."""
    where = exc.filename
    if exc.filename2 is not None and exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
        where = exc.filename2  # shutil's copy: filename is the source, filename2 the copy
    if where is None:
        where = out if isinstance(out, str) and out.strip() else "output"
    # a path holding a line break stays on the one line (as InputError.line does)
    text = os.fsdecode(where) if isinstance(where, str | bytes) else str(where)
    where = " ".join(text.splitlines())
    why = exc.strerror or type(exc).__name__
    if exc.errno in (errno.EEXIST, errno.ENOTDIR):  # "File exists" for a file as --out
        why += " (a file stands where a folder is needed)"
    return clip(
        f"sensorgap: error: {cut_name(where)}: cannot write or read: {why} "
        "(no partial file was left)"
    )


def _out_of_memory(message: str) -> bool:
    """Whether an import failed for want of memory: the loader could not map a compiled
    module (``failed to map segment from shared object``, under ``ulimit -v``)."""
    return "failed to map segment" in message or "Cannot allocate memory" in message


def _memory_line(message: str) -> str:
    """The one line of a command that ran out of memory (``MemoryError``, or a compiled
    module the loader could not map)."""
    what = message.splitlines()[0] if message else "no details"
    return (
        f"sensorgap: error: out of memory ({what}): the process may not use as much memory "
        "as the command needs (ulimit -v, a container's limit, or the machine's memory; "
        "docs/limits.md gives the peaks); its files are as after any failed command: put "
        "back, or for a search what it stored (--resume goes on)"
    )


def _thread_limit(exc: BaseException) -> bool:
    """Whether a thread or process could not be started: Python's ``RuntimeError("can't
    start new thread")``, or ``fork``/``clone`` refused (``EAGAIN``, no file named)."""
    if isinstance(exc, RuntimeError):
        return "can't start new thread" in str(exc)
    return isinstance(exc, OSError) and exc.errno == errno.EAGAIN and exc.filename is None


def _thread_line(exc: BaseException) -> str:
    """The one line of a command that could not start a thread or process."""
    what = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return (
        f"sensorgap: error: cannot start a thread ({what}): the process limit (ulimit -u, "
        "a container's pids limit) is reached; raise it or use fewer --workers; its files "
        "are as after any failed command: put back, or for a search what it stored "
        "(--resume goes on)"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point: returns the exit code (0 ok, 2 bad input, 1 internal error). Runs
    without standard streams too (``runtime.standard_streams``: started with ``>&-`` or
    ``2>&-``)."""
    with standard_streams():
        return _main(argv)


def _main(argv: Sequence[str] | None) -> int:
    top = argv is None  # the command's own process (argv from sys.argv), not a caller's
    parser = build_parser()
    argv = list(sys.argv[1:] if argv is None else argv)
    # "--extent -20,100,-5,5": glue values that start with '-' to their option
    for i in range(len(argv) - 1, 0, -1):
        if argv[i - 1] in _GLUED_OPTIONS and argv[i].startswith("-"):
            argv[i - 1 : i + 1] = [f"{argv[i - 1]}={argv[i]}"]
    try:
        args = parser.parse_args(argv)
    except StdoutUnwritable as exc:  # --help into a closed or full standard output
        print(clip(f"sensorgap: error: stdout: cannot write: {exc.reason}"), file=sys.stderr)
        return EXIT_INPUT
    func: Callable[[argparse.Namespace], int] = args.func
    if hasattr(signal, "SIGXFSZ"):  # a file-size limit: a clean OSError, not a core dump
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    _RECEIVED.clear()  # an earlier command of this process (in-process callers)
    # Ctrl-C too (hostile round nineteen, F4: a KeyboardInterrupt raised by Python's own
    # handler inside numba's compiler callback was swallowed, and the command ran on)
    previous = {sig: signal.signal(sig, _terminate) for sig in (signal.SIGINT, *_STOP_SIGNALS)}
    tune_allocator()
    out = getattr(args, "out", None)
    fresh: Path | None = None
    try:
        _check_environment()
        if func is not cmd_verify:  # a broken plugin: one line before any work (a search
            # loaded them at its first family kind, after making its --out folder)
            load_plugins()
        # an --out the command creates: removed when its standard output fails afterwards
        if isinstance(out, str) and out.strip() and not os.path.lexists(out):
            fresh = Path(out)
        for name in ("out", "catalog"):  # '' would mean the working directory
            value = getattr(args, name, None)
            if isinstance(value, str) and not value.strip():
                raise InputError(
                    f"--{name}",
                    "",
                    "must name a folder or file (an empty "
                    "path would write into the working directory)",
                )
        for name in ("environments_file", "points", "run", "road", "esmini"):
            value = getattr(args, name, None)  # '' would read a default or the cwd instead
            if isinstance(value, str) and not value.strip():
                raise InputError(
                    f"--{name.replace('_', '-')}",
                    "",
                    f"must not be empty: give a path (or a preset name), got {value!r}",
                )
        # the run folders compared: '' was the working directory (hostile round 41, F2)
        runs = [("RUN_A", getattr(args, "run_a", None)), ("RUN_B", getattr(args, "run_b", None))]
        both = getattr(args, "compare", None)
        if isinstance(both, list):
            runs += [("--compare", value) for value in both]
        for name, value in runs:
            if isinstance(value, str) and not value.strip():
                raise InputError(
                    name,
                    "",
                    "must name a run folder (an empty path would be the working directory), "
                    f"got {value!r}",
                )
        with held_until_done(), ExitStack() as locks:
            # every folder the command writes, locked before any work and until it is
            # done: a second command into it is refused (and readers need no lock)
            for folder in _written_folders(args):
                _lock_job_out(folder, locks, args.command)
                locks.enter_context(folder_lock(folder))
            for folder in _new_report_inputs(args):  # RUN/nearfield, made by this command
                _lock_job_out(folder, locks, args.command)
            # (a note such as "input changed since the run" only when the command succeeds:
            # a refused one prints its one error line)
            with guarded_stdout(), notes_after_success():
                return func(args)
    except StdoutUnwritable as exc:
        if exc.closed:
            line = (
                f"stdout: cannot write: {exc.reason}; the command stopped before any work "
                "(send it to /dev/null to discard what the command prints)"
            )
        else:
            line = (
                f"stdout: cannot write: {exc.reason} (a full device or a closed pipe); "
                f"the command stopped{_remove_fresh(fresh)}"
            )
        print(clip(f"sensorgap: error: {line}"), file=sys.stderr)
        return EXIT_INPUT
    except InputError as exc:
        _flag_sources(exc, parser, args.command)
        for text in exc.lines():  # every error found, one line each
            print(f"sensorgap: error: {text}", file=sys.stderr)
        return EXIT_INPUT
    except OSError as exc:  # disk full, file too large, permissions, a file as a folder
        line = _thread_line(exc) if _thread_limit(exc) else _os_error_line(exc, out)
        print(clip(line), file=sys.stderr)
        return EXIT_INPUT
    except MemoryError as exc:  # a memory limit (ulimit -v, a cgroup) below what it needs
        print(clip(_memory_line(str(exc))), file=sys.stderr)
        return EXIT_INPUT
    except KeyboardInterrupt as exc:
        print("sensorgap: interrupted", file=sys.stderr)
        return 128 + exc.signum if isinstance(exc, _Terminated) else 130
    except Exception as exc:  # noqa: BLE001 - the one place that turns bugs into exit 1
        if _RECEIVED:  # the stop signal raised inside a C library (matplotlib's renderer
            # turned it into "ValueError: Invalid bounding box"): an interruption all the same
            print("sensorgap: interrupted", file=sys.stderr)
            return 128 + _RECEIVED[-1]
        if isinstance(exc, ImportError) and _out_of_memory(str(exc)):
            print(clip(_memory_line(str(exc))), file=sys.stderr)
            return EXIT_INPUT
        if _thread_limit(exc):  # ulimit -u: was an internal error
            print(clip(_thread_line(exc)), file=sys.stderr)
            return EXIT_INPUT
        if args.debug:
            traceback.print_exc()
        msg = str(exc).splitlines()[0] if str(exc) else ""
        print(
            clip(
                f"sensorgap: internal error: {type(exc).__name__}: {msg} "
                "(this is a bug; rerun with --debug for the traceback)"
            ),
            file=sys.stderr,
        )
        return EXIT_INTERNAL
    finally:
        if top:
            # the command is done (its output complete, or put back as it was): a SIGTERM
            # or Ctrl-C in the interpreter's shutdown from here on ended the process with
            # 143 and no line, or a traceback (hostile round eleven, F13); the exit code
            # returned says what happened
            for sig in (signal.SIGINT, *_STOP_SIGNALS):
                signal.signal(sig, signal.SIG_IGN)
        else:
            for sig, handler in previous.items():
                signal.signal(sig, handler)


if __name__ == "__main__":
    sys.exit(main())
