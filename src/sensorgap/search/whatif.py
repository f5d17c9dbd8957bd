"""One candidate, evaluated exactly: ``sensorgap evaluate``. Reproduces any ranked row from
its family, environment, sun and parameters, and answers what-ifs (other values).

Writes ``evaluation.json`` (the ranking's metric names and values, class and reason) and
``trace.csv`` (per 20 Hz step: time; ego and target world states; the target in the ego
frame; per-sensor and fused Pd of the target's body; Pd of the confirming sensors;
P(confirmed) by then; path TTC).
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.atomic import atomic_write_bytes, removed_on_error
from sensorgap.config import load_environments
from sensorgap.config.common import finite_real, parse_decimal, shown
from sensorgap.errors import InputError
from sensorgap.filesio import (
    csv_bytes,
    path_argument,
    refuse_certified_out,
    refuse_file_on_the_way,
    write_json,
)
from sensorgap.models import Conditions, load_system
from sensorgap.scenarios import load_families
from sensorgap.scenarios.family import ParamValue
from sensorgap.search.evaluate import Evaluator, _sun_directions
from sensorgap.search.metrics import metric_names, output_value
from sensorgap.search.outcome import first_confirmation
from sensorgap.search.problem import Candidate, SearchProblem
from sensorgap.search.ranking import classify, explain
from sensorgap.search.runfolder import open_run


def parse_params(items: list[str], problem: SearchProblem) -> dict[str, ParamValue]:
    """``NAME=VALUE`` items -> the family's parameters (every one required, each once;
    numbers finite, choices from the family's list); InputError naming what is allowed."""
    space = {p.name: p for p in problem.family.space}
    out: dict[str, ParamValue] = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or name not in space:
            raise InputError(
                "param",
                "",
                f"expected NAME=VALUE with NAME one of {', '.join(space)}, got {item!r}",
            )
        if name in out:  # the last would win silently
            raise InputError("param", name, "given twice; give each parameter once")
        p = space[name]
        if p.categorical:
            if text not in p.choices:
                raise InputError(
                    "param", name, f"must be one of {', '.join(p.choices)}, got {text!r}"
                )
            out[name] = text
            continue
        try:
            v = parse_decimal(text)
        except ValueError:
            v = math.nan
        if not math.isfinite(v):
            raise InputError("param", name, f"must be a finite number, got {text!r}")
        out[name] = v  # (-0 is read as 0 by parse_decimal: hostile rounds 41 and 42)
    missing = [n for n in space if n not in out]
    if missing:
        raise InputError(
            "param",
            "",
            f"missing {', '.join(missing)} (the family "
            f"{problem.family.name!r} needs {', '.join(space)})",
        )
    return out


def parse_sun(text: str | None) -> tuple[float, float] | None:
    """``AZ/EL`` (deg, world frame: azimuth clockwise from north) or None."""
    if text is None:
        return None
    parts = text.split("/")
    try:
        az, el = parse_decimal(parts[0]), parse_decimal(parts[1])
    except (ValueError, IndexError):
        az = el = math.nan
    if (
        len(parts) != 2
        or not (math.isfinite(az) and math.isfinite(el))
        or not (0.0 <= az < 360.0 and -90.0 <= el <= 90.0)
    ):
        raise InputError(
            "sun",
            "",
            f"expected AZ/EL in degrees with 0 <= AZ < 360 and -90 <= EL <= 90, got {text!r}",
        )
    return az, el  # (-0 is read as 0 by parse_decimal)


def _check_out(out: Path) -> None:
    """``out`` must be a folder or become one (its nearest existing part a folder), not a
    certified folder nor inside one: the files it writes would be listed by no manifest
    (as ``evaluate --out``; hostile round 30: the library wrote into a run, and a file
    there was a raw FileExistsError)."""
    refuse_file_on_the_way(out, "out")
    try:
        refuse_certified_out(out, "evaluate")
    except InputError as exc:
        raise InputError("out", exc.field, exc.message.replace("--out", "out")) from None
    except (OSError, RuntimeError) as exc:
        raise InputError("out", "", f"{out}: cannot be read ({exc})") from None


def _checked_sun(sun: object) -> tuple[float, float] | None:
    """``sun`` as (azimuth, elevation), deg: None, or two real numbers with
    0 <= azimuth < 360 and -90 <= elevation <= 90 (as ``parse_sun``), else ``InputError``
    (hostile round 29: a NaN sun left a half-written trace.csv, an infinite one was "math
    domain error", azimuth 400 was accepted)."""
    if sun is None:
        return None
    pair = tuple(sun) if isinstance(sun, tuple | list) and len(sun) == 2 else (None, None)
    az, el = finite_real(pair[0]), finite_real(pair[1])
    if az is None or el is None or not (0.0 <= az < 360.0 and -90.0 <= el <= 90.0):
        raise InputError(
            "sun",
            "",
            "expected (azimuth, elevation) in degrees with 0 <= azimuth < 360 and "
            f"-90 <= elevation <= 90, got {shown(sun)}",
        )
    return az + 0.0, el + 0.0  # -0 is 0 (a float given to the library; as parse_decimal)


def evaluate_candidate(
    vehicle: str | Path | None,
    family: str | Path,
    environment: str,
    sun: tuple[float, float] | None,
    params: list[str],
    out: Path,
    environments_file: Path | None = None,
    run: Path | None = None,
) -> dict[str, Any]:
    """Evaluate one candidate exactly and write ``evaluation.json`` and ``trace.csv``
    into ``out``; returns the evaluation. ``run``: a search run folder whose recorded
    inputs (vehicle, environments, family and road, targets, reaction model) are used
    instead of ``vehicle``, ``environments_file`` and the presets. ``sun``: (azimuth,
    elevation), deg, world frame; ``params``: ``NAME=VALUE`` texts. Every argument is
    checked before any work (``InputError`` naming it)."""
    out = path_argument(out, "out")
    environments_file = (
        None if environments_file is None else path_argument(environments_file, "environments_file")
    )
    run = None if run is None else path_argument(run, "run")
    if vehicle is not None and not isinstance(vehicle, str | os.PathLike):
        raise InputError("vehicle", "", f"must be a preset name or a path, got {shown(vehicle)}")
    if isinstance(family, os.PathLike):  # a family file, as the CLI's --family path
        family = os.fspath(family)
    for name, value in (("family", family), ("environment", environment)):
        if not isinstance(value, str):
            raise InputError(name, "", f"must be a name (a str), got {shown(value)}")
    if not isinstance(params, list | tuple) or not all(isinstance(p, str) for p in params):
        raise InputError("param", "", f"must be a list of NAME=VALUE texts, got {shown(params)}")
    sun = _checked_sun(sun)
    _check_out(out)
    if run is not None:
        if vehicle is not None or environments_file is not None:
            raise InputError(
                "run",
                "",
                "give --run alone: the run folder records the "
                "vehicle and the environments (no --vehicle, "
                "--environments-file)",
            )
        rf = open_run(run, ranking=False)
        envs = rf.environments()
    else:
        if vehicle is None:
            raise InputError(
                "vehicle",
                "",
                "give --vehicle (a preset name or .toml path) or --run (a search run folder)",
            )
        given: str | Path = vehicle
        envs = load_environments(environments_file)
    if environment not in envs:
        raise InputError(
            "environment", "", f"unknown environment {environment!r}; presets: {', '.join(envs)}"
        )
    if run is not None:
        fam = rf.family(family)
        system = rf.system()
        ev = rf.evaluator("exact")
    else:
        fam = load_families([family])[0]
        system = load_system(given)
        ev = Evaluator(system, mode="exact")
    prob = SearchProblem(fam, {environment: envs[environment]}, ev)
    env_cfg = envs[environment]
    if sun is not None and (env_cfg.sun is None or not env_cfg.sun.visible):
        raise InputError("sun", "", f"environment {environment!r} has no visible sun")
    cand = Candidate(fam.name, environment, sun, parse_params(params, prob))
    res = prob.evaluate(cand, keep_trace=True, collisions_only=False)
    metrics = {m: output_value(m, res.metrics[m]) for m in metric_names()} if res.feasible else {}
    evaluation: dict[str, Any] = {
        "scenario_id": cand.scenario_id,
        "vehicle": system.name,
        "family": fam.name,
        "environment": cand.environment_label,
        "target": fam.target_class,
        "sun_azimuth_deg": None if sun is None else sun[0],
        "sun_elevation_deg": None if sun is None else sun[1],
        "params": cand.params,
        "feasible": res.feasible,
        "note": res.note,
        "class": classify(res),
        "metrics": metrics,
        "reaction": ev.reaction.label(),
        "pd": "exact",
        "bodies": ev.bodies,
    }
    trace = None
    if res.feasible:
        ex = explain(prob, cand)
        evaluation.update(
            {
                "dominant_effect": ex.dominant,
                "reason": ex.reason,
                "named_step_t_s": output_value("named_step_t_s", ex.step_t_s),
            }
        )
        trace = _trace_csv(prob, cand, ev)
    # both files or neither, and a folder it made removed (hostile round 30: a library
    # caller got trace.csv alone when evaluation.json could not be written)
    with removed_on_error(out, only=("evaluation.json", "trace.csv")):
        out.mkdir(parents=True, exist_ok=True)
        if trace is not None:
            atomic_write_bytes(out / "trace.csv", trace)
        write_json(out / "evaluation.json", evaluation)
    return evaluation


def _trace_csv(prob: SearchProblem, cand: Candidate, ev: Evaluator) -> bytes:
    sc = prob.scenario(cand)
    env = prob.environment(cand)
    tr = ev.trace(sc, env, prob.family.duration_s)
    k = len(tr.t)
    target = ev.target(sc.target_class)
    scene = ev.scene(env, target)
    psi = np.zeros(k) if tr.psi is None else tr.psi
    dirs = (
        Conditions.sun_directions(env, tr.heading)
        if cand.sun is None
        else _sun_directions(env, np.tile(np.array(cand.sun, dtype=np.float64), (k, 1)), tr.heading)
    )
    rows, pd_s = ev.exact_per_sensor(scene, tr.x, tr.y, psi, dirs, tr.occluders)
    per = np.zeros((len(ev.system.sensors), k))
    per[list(rows)] = pd_s
    pdc = tr.pd if tr.pd_confirm is None else tr.pd_confirm
    r = ev.reaction
    f = first_confirmation(pdc[None, :], np.array([k]), r.confirm_m, r.confirm_n)[0]
    ttc = np.minimum(tr.ttc, 1e6)  # inf (no collision ahead) written as 1e6 s
    cols = [
        "t_s",
        "ego_x_m",
        "ego_y_m",
        "ego_heading_rad",
        "target_x_m",
        "target_y_m",
        "target_heading_rad",
        "target_rel_x_m",
        "target_rel_y_m",
        "target_rel_heading_rad",
        *[f"{s.id}.pd" for s in ev.system.sensors],
        "pd",
        "pd_confirm",
        "p_confirmed",
        "ttc_path_s",
    ]
    data = [
        tr.t,
        sc.ego.x[:k],
        sc.ego.y[:k],
        sc.ego.heading[:k],
        sc.target.x[:k],
        sc.target.y[:k],
        sc.target.heading[:k],
        tr.x,
        tr.y,
        psi,
        *per,
        tr.pd,
        pdc,
        np.cumsum(f[:k]),
        ttc,
    ]
    return csv_bytes(cols, [np.asarray(d, dtype=np.float64) for d in data])
