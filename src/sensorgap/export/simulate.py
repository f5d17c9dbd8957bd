"""Run a catalog's scenarios in esmini and compare the simulated paths with the planned ones.

esmini is not on any package registry: the user installs it and passes ``--esmini PATH``
(or puts ``esmini`` on PATH, or sets ``SENSORGAP_ESMINI``). Each scenario runs headless with
a fixed step (``--fixed_timestep``, default 0.05 s = the sensor cycle) under a hard time
limit enforced here (esmini has none), its CSV log (``--csv_logger``) is parsed, and
``simulation.csv`` gets per scenario: whether it ran cleanly and to the scenario's end,
the largest deviation of the simulated ego and target positions from the planned ones at
the same times (<= 0.5 m), esmini's first collision of ego and target (``--collision``)
next to the plan's (agreeing within one step), for the maneuver style each relative
trigger's start and relative geometry next to the plan's (<= 0.1 s, <= 0.5 m), and the
fused Pd and risk re-evaluated along the simulated paths next to the planned values. One
scenario's failure (missing file, crash, timeout) is reported in its row; the others still
run.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import re
import shutil
import signal
import subprocess
import tempfile
import time
from array import array
from collections.abc import Iterator
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sensorgap.atomic import atomic_write_bytes
from sensorgap.config import TargetConfig
from sensorgap.errors import InputError, cut_quoted, escape_unprintable
from sensorgap.export.bodies import MAX_BODY_DEV_M, box_deviation, planned_boxes
from sensorgap.export.catalog import STYLES
from sensorgap.export.maneuver import maneuver_triggers, occluder_name, planned_origins
from sensorgap.export.spec import ScenarioSpec, read_run
from sensorgap.export.xosc import EGO, TARGET, VERSIONS, origin_path, target_origin_offset
from sensorgap.filesio import bad_entry_name, loads_json
from sensorgap.scenarios import Scenario, Trajectory
from sensorgap.scenarios.occluded import occluder_class
from sensorgap.search.evaluate import Evaluator
from sensorgap.search.metrics import compute_all
from sensorgap.search.run import ranking_csv
from sensorgap.search.runfolder import MAX_RANKED_ROWS

F64 = NDArray[np.float64]

#: Largest acceptable deviation of a simulated path from the planned one, m.
MAX_DEVIATION_M = 0.5
DEFAULT_TIMEOUT_S = 60.0
DEFAULT_STEP_S = 0.05
#: Largest acceptable difference of a maneuver-style trigger from the plan: its time, s,
#: and the relative position (triggering entity in the reference entity's frame), m.
MAX_TRIGGER_DT_S = 0.1
MAX_TRIGGER_REL_M = 0.5
#: Largest esmini log (CSV or text) read, bytes: 60 s at a 1 ms step with a few entities
#: is ~30 MB; a larger one is a bad log, never read into memory whole. Of esmini's
#: standard output and error only the last ``ESMINI_TAIL_BYTES`` are read (a program
#: that floods them -- 700 MB peaked at 4.6 GB RSS when they were captured whole).
MAX_ESMINI_LOG_BYTES = 200_000_000
#: Largest magnitude of any number read from esmini's CSV log (times, s; positions and box
#: sizes, m; headings, rad; speeds, m/s): a non-finite or larger value makes a bad log
#: (a scenario spans a few hundred metres and seconds; 1e308 overflowed the metrics).
MAX_ESMINI_LOG_VALUE = 1e6
ESMINI_TAIL_BYTES = 4096
COLUMNS = [
    "scenario_id",
    "rank",
    "style",
    "status",
    "message",
    "ran_to_end",
    "end_time_s",
    "max_dev_ego_m",
    "max_dev_target_m",
    "max_dev_relative_m",
    "within_0p5m",
    "max_dev_body_m",
    "bodies",
    "bodies_within_0p05m",
    "collision_planned_s",
    "collision_esmini_s",
    "collision_agrees",
    "triggers",
    "trigger_max_dt_s",
    "trigger_max_rel_dev_m",
    "trigger_agrees",
    "mean_pd_planned",
    "mean_pd_simulated",
    "log10_risk_planned",
    "log10_risk_simulated",
]
#: A row's esmini wall-clock time, s: kept in the returned rows and printed, never written
#: to simulation.csv (a second run with the same inputs gives the same file, byte for byte).
WALL_KEY = "esmini_wall_s"


def find_esmini(path: str | None) -> Path:
    """The esmini executable: ``path``, else ``$SENSORGAP_ESMINI``, else ``esmini`` on PATH;
    ``InputError`` (one line) when there is none."""
    env = os.environ.get("SENSORGAP_ESMINI")
    cand = path or env or shutil.which("esmini")
    if not cand:
        raise InputError(
            "esmini",
            "",
            "esmini is not installed: give --esmini PATH (or put "
            "esmini on PATH); it is not on any package registry",
        )
    # named by where it came from (hostile round 26: a bad SENSORGAP_ESMINI was blamed
    # on --esmini, which was not given)
    source = "esmini" if path else "SENSORGAP_ESMINI" if env else "PATH"
    p = Path(cand)
    if not (p.is_file() and os.access(p, os.X_OK)):
        shown = cand if cand.strip() == cand else repr(cand)
        raise InputError(source, "", f"{shown} is not an executable file")
    # absolute, as checked here: esmini runs in a temporary folder (and a bare name would
    # be looked up on PATH), so a relative path would name another file or none
    return Path(os.path.abspath(p))


@dataclass
class SimPaths:
    """Simulated states per entity: t (s), x, y (m), heading (rad), speed (m/s); its
    bounding box as esmini logs it: centre in the entity's frame bb_x, bb_y, and length,
    width (m; empty when the log has no box columns); its velocity vx, vy (m/s, world)."""

    states: dict[str, tuple[F64, F64, F64, F64, F64]]
    boxes: dict[str, tuple[F64, F64, F64, F64]] = field(default_factory=dict)
    velocity: dict[str, tuple[F64, F64]] = field(default_factory=dict)


_STATE_COLUMNS = ("World_Position_X", "World_Position_Y", "World_Heading_Angle", "Current_Speed")
#: Longest line of esmini's CSV log read, characters (a row of ten entities is ~3 kB).
MAX_ESMINI_LOG_LINE = 1_000_000


def _log_lines(path: Path) -> Iterator[tuple[int, str]]:
    """The lines of a log with their numbers (1-based), one at a time; ValueError for a
    line longer than ``MAX_ESMINI_LOG_LINE``."""
    with open(path, encoding="utf-8", errors="replace") as f:
        n = 0
        while line := f.readline(MAX_ESMINI_LOG_LINE + 1):
            n += 1
            if len(line) > MAX_ESMINI_LOG_LINE:
                raise ValueError(f"{path}: line {n}: longer than {MAX_ESMINI_LOG_LINE} characters")
            yield n, line.rstrip("\r\n")


def parse_esmini_csv(path: Path) -> SimPaths:
    """esmini's ``--csv_logger`` file: one row per step, one column block per entity. Read
    a line at a time, keeping only the numbers used: 8 bytes each (hostile round 29: every
    line and field kept as text took ~110 bytes of memory per byte of log, 2.5 GB for
    20 MB)."""
    size = path.stat().st_size
    if size > MAX_ESMINI_LOG_BYTES:
        raise ValueError(f"{path}: {size} bytes; at most {MAX_ESMINI_LOG_BYTES} read")
    lines = _log_lines(path)
    cols: list[str] | None = None
    for _, line in lines:
        if line.startswith("Index"):
            cols = [c.strip() for c in line.split(",")]
            break
    if cols is None:
        raise ValueError(f"{path}: no header line in esmini's CSV log")
    # each column by its entity number and name (its unit, [..], dropped), the
    # first of equal ones: a lookup, not a scan of the header per column (hostile round
    # 30: 9 scans of the header per entity took 282 s for 9,000 entities)
    index: dict[tuple[str, str], int] = {}
    for i, c in enumerate(cols):
        m = re.match(r"#(\d{1,6}) ([^\s\[]+)", c)
        if m is not None:
            index.setdefault((m.group(1), m.group(2)), i)

    def col(k: int, name: str) -> int:
        i = index.get((str(k), name))
        if i is None:
            raise ValueError(f"{path}: column #{k} {name} missing")
        return i

    def optional(k: int, names: list[str]) -> list[int] | None:
        try:
            return [col(k, n) for n in names]
        except ValueError:
            return None

    n_ent = max((int(m.group(1)) for c in cols if (m := re.match(r"#(\d{1,6}) ", c))), default=0)
    if n_ent < 1:
        raise ValueError(f"{path}: no entity columns (#1 ...) in esmini's CSV log")
    # the columns read: the time, then per entity its name, state, box and velocity
    names: list[int] = []
    blocks: list[tuple[list[int], list[int] | None, list[int] | None]] = []
    for k in range(1, n_ent + 1):
        names.append(col(k, "Entity_Name"))
        state = [col(k, n) for n in _STATE_COLUMNS]
        bb = optional(k, [f"bb_{n}" for n in ("x", "y", "length", "width")])
        velocity = optional(k, ["Vel_X", "Vel_Y"]) if bb is not None else None
        blocks.append((state, bb, velocity))
    numeric = [1] + [i for st, bb, v in blocks for i in (*st, *(bb or ()), *(v or ()))]
    need = max(numeric + names)
    values = array("d")
    first: list[str] = []
    for n, line in lines:
        if not line.strip():
            continue
        row = line.split(",")
        if len(row) <= need:  # a row too short for a column read: a bad log
            raise ValueError(
                f"{path}: line {n}: {len(row)} fields, no column {need + 1} "
                f"({cols[need]}; a truncated log?)"
            )
        if not first:
            first = [row[i].strip() for i in names]
        for i in numeric:
            try:
                number = float(row[i])
                # float() also reads '1_0' and other scripts' digits ('١'), which no CSV
                # reader takes for numbers (remark of session 26)
                if "_" in row[i] or not row[i].isascii():
                    raise ValueError(row[i])
            except ValueError:
                shown = cut_quoted(repr(row[i].strip()))
                raise ValueError(f"{path}: line {n}: {cols[i]} is {shown}; not a number") from None
            if not abs(number) <= MAX_ESMINI_LOG_VALUE:  # also true for nan
                raise ValueError(
                    f"{path}: line {n}: {cols[i]} is {row[i].strip()}; every number must be "
                    f"finite and within +-{MAX_ESMINI_LOG_VALUE:g}"
                )
            values.append(number)
    if not first:
        raise ValueError(f"{path}: no data rows in esmini's CSV log")
    arr = np.frombuffer(values, dtype=np.float64).reshape(-1, len(numeric))
    at = {i: j for j, i in enumerate(numeric)}
    t = arr[:, 0]
    out: dict[str, tuple[F64, F64, F64, F64, F64]] = {}
    boxes: dict[str, tuple[F64, F64, F64, F64]] = {}
    vel: dict[str, tuple[F64, F64]] = {}
    for name, (state, bb, vcols) in zip(first, blocks, strict=True):
        x, y, h, speed = (arr[:, at[i]] for i in state)
        out[name] = (t, x, y, np.unwrap(h), speed)
        # an esmini without the box or velocity columns: the box and velocity checks say
        # so; a bad value in them is a bad log, as anywhere
        if bb is not None:
            bx, by, bl, bw = (arr[:, at[i]] for i in bb)
            boxes[name] = (bx, by, bl, bw)
            if vcols is not None:
                vel[name] = (arr[:, at[vcols[0]]], arr[:, at[vcols[1]]])
    return SimPaths(out, boxes, vel)


def _deviation(planned: Trajectory, t: F64, x: F64, y: F64) -> float:
    keep = t <= planned.t[-1] + 1e-9
    px = np.interp(t[keep], planned.t, planned.x)
    py = np.interp(t[keep], planned.t, planned.y)
    return float(np.max(np.hypot(x[keep] - px, y[keep] - py))) if keep.any() else float("inf")


def _simulated_scenario(
    sim: SimPaths, planned: Scenario, target: TargetConfig, occluder: TargetConfig | None = None
) -> Scenario:
    """The scenario esmini played: ego and target (and the occluders the file has as
    entities, the maneuver style) from the log at the planned times; occluders the file
    does not have (the replay style) stay where the plan has them."""

    def traj(name: str, ref: Trajectory) -> Trajectory:
        t, x, y, h, v = sim.states[name]
        tt = ref.t
        return Trajectory(
            tt,
            np.interp(tt, t, x),
            np.interp(tt, t, y),
            np.interp(tt, t, h),
            np.abs(np.interp(tt, t, v)),
        )

    # esmini logs each entity's origin: the target's rear axle -> back to its box centre
    ahead = target_origin_offset(target)
    occs = []
    for occ in planned.occluders:
        name = occluder_name(occ.label)
        if name in sim.states and occluder is not None:
            back = target_origin_offset(occluder)
            occ = replace(occ, path=origin_path(traj(name, occ.path), -back))
        occs.append(occ)
    return Scenario(
        traj(EGO, planned.ego),
        origin_path(traj(TARGET, planned.target), -ahead),
        planned.target_class,
        tuple(occs),
    )


#: esmini's log line of the first contact of the ego and the target (``--collision``;
#: contacts with occluders are not collisions of the plan).
COLLISION_RE = re.compile(
    r"\[(\d+(?:\.\d+)?)\] \[\w+\] Collision between "
    rf"(?:{EGO} and {TARGET}|{TARGET} and {EGO})\b"
)
#: esmini's log line of an event starting.
EVENT_START_RE = re.compile(
    r"^\[(-?\d+(?:\.\d+)?)\] \[\w+\] (\S+) standbyState -> "
    r"startTransition -> runningState",
    re.M,
)


def event_starts(text: str) -> dict[str, float]:
    """First start time (s) of every storyboard element in an esmini text log."""
    out: dict[str, float] = {}
    for m in EVENT_START_RE.finditer(text):
        t = float(m.group(1))
        if math.isfinite(t):  # a time of 400 digits is no time: that start is not read
            out.setdefault(m.group(2), t)
    return out


def _pose_at(t: F64, x: F64, y: F64, h: F64, at: float) -> tuple[float, float, float]:
    return (float(np.interp(at, t, x)), float(np.interp(at, t, y)), float(np.interp(at, t, h)))


def _relative(actor: tuple[float, float, float], ref: tuple[float, float, float]) -> F64:
    """``actor``'s position in ``ref``'s frame (longitudinal, lateral), m."""
    dx, dy = actor[0] - ref[0], actor[1] - ref[1]
    c, s = math.cos(ref[2]), math.sin(ref[2])
    return np.array([c * dx + s * dy, -s * dx + c * dy])


def relative_deviation(spec: ScenarioSpec, sim: SimPaths) -> float:
    """Largest distance (m) between esmini's and the plan's position of the target
    relative to the ego, at the logged times within the plan (both in the planned ego's
    frame, so a heading difference of a few mrad does not swing a distant target)."""
    plans = planned_origins(spec)
    pe, pt = plans[EGO], plans[TARGET]
    te, xe, ye = sim.states[EGO][:3]
    tt, xt, yt = sim.states[TARGET][:3]
    keep = te <= pe.t[-1] + 1e-9
    worst = 0.0
    for k in np.flatnonzero(keep):
        t = float(te[k])
        ego_p = _pose_at(pe.t, pe.x, pe.y, pe.heading, t)
        rel_e = _relative(
            (float(np.interp(t, tt, xt)), float(np.interp(t, tt, yt)), 0.0),
            (float(xe[k]), float(ye[k]), ego_p[2]),
        )
        rel_p = _relative(_pose_at(pt.t, pt.x, pt.y, pt.heading, t), ego_p)
        worst = max(worst, float(np.hypot(*(rel_e - rel_p))))
    return worst


def trigger_checks(
    spec: ScenarioSpec, sim: SimPaths, starts: dict[str, float], step_s: float = DEFAULT_STEP_S
) -> list[tuple[str, float, float]]:
    """Per relative trigger of the maneuver style: (event; esmini's start minus the
    plan's, s; how far the triggering entity's position relative to the reference entity
    (in the reference's own frame, as the condition sees it) passed from the plan's
    relative position at the planned trigger during the step in
    which esmini's condition became true, m). esmini starts an event at the first step its
    condition holds, up to one step after the instant it became true; that delay is in
    the time, not in the geometry. An event that never started: (event, inf, inf)."""
    plans = planned_origins(spec)
    out = []
    for trig in maneuver_triggers(spec):
        t_e = starts.get(trig.event)
        if t_e is None or trig.actor not in sim.states or trig.reference not in sim.states:
            out.append((trig.event, math.inf, math.inf))
            continue
        a, r = sim.states[trig.actor], sim.states[trig.reference]
        r0, r1 = (
            _relative(_pose_at(a[0], a[1], a[2], a[3], t), _pose_at(r[0], r[1], r[2], r[3], t))
            for t in (max(t_e - step_s, 0.0), t_e)
        )
        pa, pr = plans[trig.actor], plans[trig.reference]
        rel_p = _relative(
            _pose_at(pa.t, pa.x, pa.y, pa.heading, trig.time_s),
            _pose_at(pr.t, pr.x, pr.y, pr.heading, trig.time_s),
        )
        seg = r1 - r0
        lam = float(
            np.clip(np.dot(rel_p - r0, seg) / max(float(np.dot(seg, seg)), 1e-18), 0.0, 1.0)
        )
        out.append((trig.event, t_e - trig.time_s, float(np.hypot(*(r0 + lam * seg - rel_p)))))
    return out


def body_deviations(spec: ScenarioSpec, sim: SimPaths) -> dict[str, float]:
    """Per entity of the plan that esmini logged with its box: the largest distance (m)
    of the logged box's centre or corners from the planned box's (``export.bodies``)."""
    out = {}
    for name, plan in planned_boxes(spec).items():
        if name in sim.states and name in sim.boxes:
            t, x, y, h, _ = sim.states[name]
            out[name] = box_deviation(plan, t, x, y, h, *sim.boxes[name])
    return out


def run_esmini(
    esmini: Path, xosc: Path, tmp: Path, timeout_s: float, step_s: float
) -> tuple[Path, str] | str:
    """Run one scenario file in esmini (headless, fixed step ``step_s`` s, ``--collision``)
    in the folder ``tmp`` under the hard limit ``timeout_s`` (s): (its CSV log, its text
    log), or a one-line reason it failed (``timeout: ...``, ``error: ...``, ``crashed:
    ...``)."""
    log = tmp / "log.csv"
    text_log = tmp / "esmini.txt"
    cmd = [
        str(esmini),
        "--headless",
        "--osc",
        str(xosc.resolve()),
        "--fixed_timestep",
        repr(step_s),
        "--csv_logger",
        str(log),
        "--collision",
        "--disable_stdout",
        "--logfile_path",
        str(text_log),
    ]
    outputs = (tmp / "esmini.stdout", tmp / "esmini.stderr")
    try:  # into files, of which only the tails are read (memory stays bounded)
        with outputs[0].open("wb") as out, outputs[1].open("wb") as err:
            # a session of its own: a timeout kills what a wrapper script started, too
            proc = subprocess.Popen(cmd, cwd=tmp, stdout=out, stderr=err, start_new_session=True)
            try:
                proc.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(OSError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                return f"timeout: esmini did not finish within {timeout_s:g} s (killed)"
            finally:
                if proc.poll() is None:  # an interrupt while waiting
                    with contextlib.suppress(OSError):
                        os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
                # what a wrapper script left running in esmini's session once it ended
                # (hostile round 37: a fake esmini's '( sleep 123 ) &' outlived simulate
                # and kept writing into this temporary folder)
                with contextlib.suppress(OSError):
                    os.killpg(proc.pid, signal.SIGKILL)
    except OSError as exc:
        return f"error: cannot run esmini: {_start_failure(exc, esmini)}"
    if proc.returncode != 0 or not log.is_file():
        tail = _tail(outputs[1]) or _tail(outputs[0])
        # its last line, control characters escaped (a terminal's escape sequences were
        # printed and written to simulation.csv raw: hostile round eighteen, F12)
        last = escape_unprintable(tail.splitlines()[-1]) if tail else ""
        if proc.returncode == 0:  # (it was called "crashed: esmini exit code 0")
            why = f"esmini ended with exit code 0 without writing {log.name}"
            return f"bad log: {why}: {last}"[:300]
        return f"crashed: esmini exit code {proc.returncode}: {last}"[:300]
    if text_log.is_file() and text_log.stat().st_size > MAX_ESMINI_LOG_BYTES:
        return f"bad log: {text_log}: larger than {MAX_ESMINI_LOG_BYTES} bytes"
    text = text_log.read_text(encoding="utf-8", errors="replace") if text_log.is_file() else ""
    return log, text


def _start_failure(exc: OSError, esmini: Path) -> str:
    """Why esmini could not be started, in words: a missing file reported for a program
    that exists is its ``#!`` interpreter (a script saved with Windows line ends asks for
    ``/bin/sh\\r``; it read "No such file or directory", naming the script)."""
    if exc.errno == errno.ENOENT and esmini.is_file():
        try:
            with esmini.open("rb") as f:
                first = f.readline(256)
        except OSError:
            first = b""
        if first.startswith(b"#!"):
            line = escape_unprintable(first[2:].decode("utf-8", "backslashreplace").rstrip("\n"))
            crlf = " (the line ends in a carriage return: saved with Windows line ends)"
            return f"{esmini}: the interpreter of its #! line ({line.strip()}) was not found" + (
                crlf if first.rstrip(b"\n").endswith(b"\r") else ""
            )
    return str(exc)


def _tail(path: Path) -> str:
    """The last ``ESMINI_TAIL_BYTES`` of a file as text, stripped."""
    with path.open("rb") as f:
        f.seek(max(0, path.stat().st_size - ESMINI_TAIL_BYTES))
        # undecodable bytes as \\xNN (the caller escapes control characters)
        return f.read().decode("utf-8", "backslashreplace").strip()


def without_temporary_folder(message: str, tmp: Path) -> str:
    """``message`` with the path of esmini's temporary output folder ``tmp`` (a new random
    name each run) left out: its files named as esmini names them (``log.csv``), so the
    same inputs give the same ``simulation.csv`` (hostile rounds 32 and 33: the random
    folder was written into the row's message, of a plain run and of a reaction run)."""
    return message.replace(f"{tmp}/", "").replace(str(tmp), "esmini's output folder")


def run_one(
    esmini: Path,
    xosc: Path,
    spec: ScenarioSpec,
    evaluator: Evaluator,
    timeout_s: float,
    step_s: float,
    style: str = "replay",
) -> dict[str, Any]:
    """Simulate one scenario of an export ``style``; a row of ``simulation.csv``."""
    row: dict[str, Any] = {"scenario_id": spec.scenario_id, "rank": spec.rank, "style": style}
    with tempfile.TemporaryDirectory(prefix="sensorgap-esmini-") as tmp:
        t0 = time.perf_counter()
        res = run_esmini(esmini, xosc, Path(tmp), timeout_s, step_s)
        if isinstance(res, str):
            status, _, message = res.partition(": ")
            if status != "timeout":
                row[WALL_KEY] = round(time.perf_counter() - t0, 3)
            message = without_temporary_folder(message, Path(tmp))
            return {**row, "status": status, "message": message}
        row[WALL_KEY] = round(time.perf_counter() - t0, 3)
        log, text = res
        try:
            sim = parse_esmini_csv(log)
            if EGO not in sim.states or TARGET not in sim.states:
                raise ValueError(f"entities in the log: {', '.join(sim.states)}")
            first, end = float(sim.states[EGO][0][0]), float(spec.scenario.ego.t[-1])
            if first > end + 1e-9:  # nothing to compare (hostile round 29: an inf written)
                raise ValueError(
                    f"{log}: its first step (t = {first:g} s) is after the planned end ({end:g} s)"
                )
        except ValueError as exc:
            message = without_temporary_folder(str(exc), Path(tmp))[:300]
            return {**row, "status": "bad log", "message": message}
        hit = COLLISION_RE.search(text)
    planned = spec.scenario
    dev_e = _deviation(planned.ego, *sim.states[EGO][:3])
    # the target's logged origin is its rear axle (vehicles): compare with that point's plan
    dev_t = _deviation(
        origin_path(planned.target, target_origin_offset(spec.target)), *sim.states[TARGET][:3]
    )
    bodies = body_deviations(spec, sim)
    dev_b = max(bodies.values(), default=math.inf)
    bodies_ok = dev_b <= MAX_BODY_DEV_M
    occ_class = spec.family.settings.get("occluder")
    # the run's target and occluder classes (its recorded targets), as the export's
    sc_sim = _simulated_scenario(
        sim, planned, spec.target, None if occ_class is None else occluder_class(spec.family)
    )
    tr_p = evaluator.trace(planned, spec.environment, spec.family.duration_s)
    tr_s = evaluator.trace(sc_sim, spec.environment, spec.family.duration_s)
    m_p, m_s = compute_all(tr_p), compute_all(tr_s)
    dev_r = relative_deviation(spec, sim)
    ok = max(dev_e, dev_t, dev_r) <= MAX_DEVIATION_M
    # ran to the end: the log reaches the scenario's duration (a StopTrigger that fires
    # earlier, or a crash mid-run, is a failure); the maneuver style's StopTrigger ends the
    # run at the ego's collision with the target, which is its end then
    t_end = float(sim.states[EGO][0][-1]) if len(sim.states[EGO][0]) else 0.0
    t_plan = float(tr_p.t[-1]) if tr_p.collided else None
    t_sim = float(hit.group(1)) if hit else None
    late = t_sim is not None and t_sim > spec.family.duration_s + 1e-9
    if late:  # the step esmini takes past the duration: outside the plan, not compared
        t_sim = None
    end = t_sim if style == "maneuver" and t_sim is not None else spec.family.duration_s
    to_end = t_end >= end - step_s - 1e-9
    agree = (t_plan is None and t_sim is None) or (
        t_plan is not None and t_sim is not None and abs(t_plan - t_sim) <= step_s + 1e-9
    )
    trig = trigger_checks(spec, sim, event_starts(text), step_s) if style == "maneuver" else []
    # an event esmini never started (trigger_checks: inf) is no number of the row: named
    # in the message and in ``triggers`` (it was an internal error writing inf)
    fired = [c for c in trig if math.isfinite(c[1]) and math.isfinite(c[2])]
    never = [c[0] for c in trig if c not in fired]
    dt_max = max((abs(c[1]) for c in fired), default=0.0)
    rel_max = max((c[2] for c in fired), default=0.0)
    differs = dt_max > MAX_TRIGGER_DT_S + 1e-9 or rel_max > MAX_TRIGGER_REL_M
    trig_ok = not never and not differs
    msgs = [
        m
        for m, bad in (
            ("path deviates by more than 0.5 m", not ok),
            (f"stopped at {t_end:g} s before the end", not to_end),
            ("collision differs from the plan", not agree),
            ("a trigger differs from the plan by more than 0.1 s / 0.5 m", differs),
            (f"esmini never started {', '.join(never)}", bool(never)),
            ("a body is more than 0.05 m from the plan", style == "replay" and not bodies_ok),
            ("esmini's first collision is after the planned duration (not compared)", late),
        )
        if bad
    ]
    return {
        **row,
        "status": "ok" if to_end else "stopped early",
        "message": "; ".join(msgs),
        "ran_to_end": "yes" if to_end else "no",
        "end_time_s": round(t_end, 3),
        "max_dev_ego_m": round(dev_e, 4),
        "max_dev_target_m": round(dev_t, 4),
        "max_dev_relative_m": round(dev_r, 4),
        "within_0p5m": "yes" if ok else "no",
        "max_dev_body_m": round(dev_b, 4) if bodies else "",
        "bodies": " ".join(f"{n}:{d:.4f}" for n, d in bodies.items()),
        "bodies_within_0p05m": ("yes" if bodies_ok else "no") if bodies else "",
        "collision_planned_s": "" if t_plan is None else round(t_plan, 3),
        "collision_esmini_s": "" if t_sim is None else round(t_sim, 3),
        "collision_agrees": "yes" if agree else "no",
        "triggers": " ".join(
            f"{e}:{dt:+.3f}s/{d:.3f}m" if e not in never else f"{e}:never" for e, dt, d in trig
        ),
        "trigger_max_dt_s": round(dt_max, 4) if fired else "",
        "trigger_max_rel_dev_m": round(rel_max, 4) if fired else "",
        "trigger_agrees": ("yes" if trig_ok else "no") if trig else "",
        "mean_pd_planned": round(m_p["mean_pd"], 6),
        "mean_pd_simulated": round(m_s["mean_pd"], 6),
        "log10_risk_planned": round(m_p["log10_risk"], 4),
        "log10_risk_simulated": round(m_s["log10_risk"], 4),
    }


def read_catalog_index(path: Path) -> tuple[dict[str, Any], list[dict[str, Any]]]:
    """``catalog.json`` and its scenario entries, checked: a JSON object whose
    ``scenarios`` is a list of objects, each with a ``scenario_id`` and a ``file`` (a
    relative path inside the catalog) and, if given, a ``road`` of the same kind;
    anything else -> ``InputError`` naming the file and the field."""
    try:
        index = loads_json(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise InputError(path, "", f"malformed catalog index: {exc}") from None
    except RecursionError:
        raise InputError(path, "", "malformed catalog index: nested too deeply") from None
    if not isinstance(index, dict):
        raise InputError(path, "", "malformed catalog index: expected a JSON object")
    entries = index.get("scenarios")
    if not isinstance(entries, list):
        raise InputError(path, "scenarios", "malformed catalog index: expected a list")
    for i, entry in enumerate(entries):
        if not isinstance(entry, dict):
            raise InputError(
                path,
                f"scenarios[{i}]",
                f"malformed catalog index: expected an object, got {type(entry).__name__}",
            )
        for key in ("scenario_id", "file", "road"):
            v = entry.get(key)
            if key == "road" and v is None:
                continue
            if (
                not isinstance(v, str)
                or not v
                or Path(v).is_absolute()
                or (key != "scenario_id" and ".." in Path(v).parts)
                or (key == "road" and not v.endswith(".xodr"))
            ):
                # a road is an OpenDRIVE file (hostile round 23: the scenario's own .xosc
                # or ranking.json was taken as the braking ego's road)
                want = {
                    "scenario_id": "a string",
                    "file": "a relative path inside the catalog",
                    "road": "a relative path of an .xodr file inside the catalog",
                }[key]
                raise InputError(
                    path, f"scenarios[{i}].{key}", f"malformed catalog index: expected {want}"
                )
        rank = entry.get("rank")  # copied into simulation.csv: a finite rank
        if rank is not None and (
            not isinstance(rank, int) or isinstance(rank, bool) or not 1 <= rank <= MAX_RANKED_ROWS
        ):
            raise InputError(
                path,
                f"scenarios[{i}].rank",
                f"malformed catalog index: expected a positive integer (1..{MAX_RANKED_ROWS}), "
                f"got {cut_quoted(repr(rank))}",
            )
    for key in ("style", "osc_version"):
        if not isinstance(index.get(key, ""), str):
            raise InputError(path, key, "malformed catalog index: expected a string")
    # what export writes, nothing else: an unknown version reached the writer of the
    # braking ego (simulate --ego-reaction) as a KeyError (hostile round 23)
    for key, allowed in (("style", STYLES), ("osc_version", tuple(VERSIONS))):
        if key in index and index[key] not in allowed:
            raise InputError(
                path,
                key,
                f"malformed catalog index: expected one of {', '.join(allowed)}, "
                f"got {cut_quoted(repr(index[key]))}",
            )
    if "files" not in index:  # every export lists its files (hostile round twenty, F2)
        raise InputError(
            path,
            "files",
            "malformed catalog index: missing (an export lists every file it wrote with its "
            "sha256); export again",
        )
    _check_catalog_files(path, index["files"])
    for i, entry in enumerate(entries):  # a scenario the record leaves out is unchecked
        for key in ("file", "road"):
            if entry.get(key) is not None and entry[key] not in index["files"]:
                raise InputError(
                    path,
                    f"scenarios[{i}].{key}",
                    "malformed catalog index: not listed under files with its sha256 (an "
                    "export lists every file it wrote); export again",
                )
    return index, entries


def _check_catalog_files(path: Path, files: Any) -> None:
    """Every file ``catalog.json`` lists under ``files`` (scenarios, roads, coverage maps,
    the ranking) is, byte for byte, what the export wrote (its ``sha256``); else
    ``InputError`` naming the file. A scenario file swapped for another's, a road or map
    replaced, or ranking.csv edited, with the manifest re-hashed, was reported (the
    report linked rank 2's scenario under rank 1's id) and simulated (hostile round
    eighteen, F6). A listed file that is gone is left to the reader (the report shows
    the loss, ``verify`` names it). ``"files": null`` is malformed (it switched the check
    off: round nineteen), so is a catalog without ``files`` or one whose scenario file or
    road is not listed there (``read_catalog_index``: round twenty)."""
    from sensorgap.provenance import sha256_of

    if not isinstance(files, dict):  # null too: an export always writes the object
        raise InputError(path, "files", "malformed catalog index: expected an object")
    root = path.parent
    for rel, meta in sorted(files.items()):
        digest = meta.get("sha256") if isinstance(meta, dict) else None
        size = meta.get("bytes") if isinstance(meta, dict) else None
        if (
            not isinstance(digest, str)
            or not isinstance(size, int)
            or isinstance(size, bool)
            or size < 0
            or bad_entry_name(rel) is not None
        ):
            raise InputError(
                path,
                f"files.{str(rel)[:80]}",
                "malformed catalog index: expected a relative path inside the catalog "
                "with its bytes and sha256",
            )
        file = root / rel
        if file.is_symlink() or not file.is_file():
            continue  # lost: the report says so where it shows it, verify names it
        if file.stat().st_size != size or sha256_of(file) != digest:
            raise InputError(
                file,
                "",
                "is not the file the export wrote (its SHA-256 is not the one catalog.json "
                "records): changed after the export; restore it or export again",
            )


#: Shortest fixed simulation step, s: 1 kHz (a 1e-9 s step made esmini take 1e10 steps
#: for a 10 s scenario, each ending in the timeout); and the shortest timeout, s (a
#: subnormal 1e-320 s is no meaningful limit; 1 ms still kills every run at once, as a test does).
MIN_STEP_S = 1e-3
MIN_TIMEOUT_S = 1e-3


def simulate_catalog(
    catalog: Path,
    esmini: str | None = None,
    timeout_s: float = DEFAULT_TIMEOUT_S,
    step_s: float = DEFAULT_STEP_S,
    ego_reaction: bool = False,
) -> list[dict[str, Any]]:
    """Run every scenario of ``catalog`` (see the module docstring); with
    ``ego_reaction`` also the reaction runs (``export.reaction``: columns ``react_*``);
    writes ``simulation.csv`` and returns its rows."""
    catalog = Path(catalog)
    index_path = catalog / "catalog.json"
    if not catalog.is_dir():
        raise InputError(catalog, "", "catalog folder does not exist")
    if not index_path.is_file():
        raise InputError(
            index_path, "", "not a catalog (catalog.json is missing); run `sensorgap export` first"
        )
    if not (MIN_TIMEOUT_S <= timeout_s <= 86_400.0):
        raise InputError(
            "timeout", "", f"must be within {MIN_TIMEOUT_S:g}..86400 s, got {timeout_s!r}"
        )
    if not (MIN_STEP_S <= step_s <= 1.0):
        raise InputError("step", "", f"must be within {MIN_STEP_S:g}..1 s, got {step_s!r}")
    index, entries = read_catalog_index(index_path)
    if ego_reaction:  # the braking ego is written on the scenario's road: named by each
        for i, entry in enumerate(entries):
            if entry.get("road") is None:
                raise InputError(
                    index_path,
                    f"scenarios[{i}].road",
                    "malformed catalog index: missing; simulate --ego-reaction writes the "
                    "braking ego's scenario on the scenario's road (every export names it)",
                )
    exe = find_esmini(esmini)
    run = read_run(catalog)
    system = run.system()  # the recorded inputs of the run, never a preset of that name
    evaluator = run.evaluator("exact")
    by_id = {str(r["scenario_id"]): r for r in run.rows}
    rows = []
    for entry in entries:
        sid = str(entry["scenario_id"])
        xosc = catalog / str(entry["file"])
        base = {"scenario_id": sid, "rank": entry.get("rank")}
        if not xosc.is_file():
            rows.append({**base, "status": "missing", "message": f"{xosc} does not exist"})
            continue
        if sid not in by_id:
            rows.append({**base, "status": "missing", "message": "scenario not in ranking.json"})
            continue
        spec = ScenarioSpec.from_row(by_id[sid], system, catalog / "ranking.json", run)
        style = str(index.get("style", "replay"))
        row = run_one(exe, xosc, spec, evaluator, timeout_s, step_s, style)
        if ego_reaction:
            from sensorgap.export.reaction import reaction_columns

            cols, msgs = reaction_columns(
                spec,
                evaluator,
                exe,
                style,
                str(index.get("osc_version", "1.2")),
                catalog / str(entry.get("road", "")),
                timeout_s,
                step_s,
            )
            row.update(cols)
            row["message"] = "; ".join(m for m in [row.get("message", ""), *msgs] if m)
        rows.append(row)
    for row in rows:  # esmini's words (its output's tail, a file name) as text, escaped
        row["message"] = escape_unprintable(str(row.get("message", "")))
    columns = COLUMNS
    if ego_reaction:
        from sensorgap.export.reaction import COLUMNS as REACTION_COLUMNS

        columns = COLUMNS + REACTION_COLUMNS
    atomic_write_bytes(catalog / "simulation.csv", ranking_csv(rows, columns))
    return rows
