"""``sensorgap tradeoff``: what each approximation costs and saves, measured in one run.

1. Grid resolution (0.5, 0.2, 0.1, 0.05, 0.02 m) against time and the error of
   (a) the near-field blind-spot area (grid vs the exact polygons) and (b) Pd along paths
   (bilinear lookup in a grid vs exact evaluation at the path points).
2. Map lookup vs exact evaluation in the search: time per candidate, error of the collision
   probability, candidates whose class (sensor-critical or not) changes, top-10 overlap.
3. Scene-limited vs full exact evaluation (``coverage.scope``): time; results identical.
4. Target bodies vs points (the paper's setting): the added cost of bodies and how much the
   point model's answer differs.

Writes ``tradeoff.csv``, ``tradeoff.md``, ``resolution.png`` and ``manifest.json``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from sensorgap.analysis.nearfield import blind_spots, grid_blind_spots
from sensorgap.atomic import atomic_write_bytes, atomic_write_text
from sensorgap.config import load_environment, load_environments, load_target
from sensorgap.config.load import require_shipped
from sensorgap.coverage import GridSpec, Scene, evaluate_grid, evaluate_points
from sensorgap.coverage.logmiss import interpolate_map
from sensorgap.coverage.plot import save_figure
from sensorgap.filesio import write_manifest
from sensorgap.models import Conditions, load_system
from sensorgap.scenarios import load_family
from sensorgap.search.evaluate import Evaluator
from sensorgap.search.problem import SearchProblem
from sensorgap.search.run import ranking_csv

RESOLUTIONS = (0.5, 0.2, 0.1, 0.05, 0.02)


#: What the trade-off measures on: a vehicle, the environments and families of the search
#: study (the grid study uses rain_25 and a car).
SYSTEM = "system_a"
ENVIRONMENTS = ("clear", "glare_front_right", "rain_25", "fog_50")
FAMILIES = ("slow_ahead_curve", "cut_in_right")


def _timed(fn: Callable[[], Any]) -> tuple[float, Any]:
    t0 = time.perf_counter()
    out = fn()
    return time.perf_counter() - t0, out


def resolution_rows(system_name: str, resolutions: tuple[float, ...]) -> list[dict[str, Any]]:
    """Blind-spot area and path-Pd error and time per grid resolution."""
    system = load_system(system_name)
    exact_area = sum(p.area for p in blind_spots(system))
    car = load_target("car")
    scene = Scene(system, car, Conditions.from_config(load_environment("rain_25")))
    # paths: the lanes beside and ahead (straight, vehicle frame), 0.25 m spacing
    xs = np.arange(-30.0, 150.0, 0.25)
    paths = [
        np.column_stack([xs, np.full_like(xs, y), np.full_like(xs, car.reference_height_m)])
        for y in (-3.5, 0.0, 3.5)
    ]
    pts = np.vstack(paths)
    t_exact, cov = _timed(lambda: evaluate_points(scene, pts))
    rows = []
    for res in resolutions:
        t0 = time.perf_counter()
        g = grid_blind_spots(system, res)
        t_bs = time.perf_counter() - t0
        grid = GridSpec(-32.0, 152.0, -6.0, 6.0, res, car.reference_height_m)
        t0 = time.perf_counter()
        gc = evaluate_grid(scene, grid, workers=2)
        t_grid = time.perf_counter() - t0
        look, inside = interpolate_map(grid, gc.fused, pts[:, 0], pts[:, 1])
        assert bool(np.all(inside == 1))
        err = np.abs(look - cov.fused)
        rows.append(
            {
                "study": "grid resolution",
                "setting": f"{res:g} m",
                "time_s": t_bs,
                "blind_spot_m2": g.area,
                "blind_spot_exact_m2": exact_area,
                "error": abs(g.area - exact_area),
                "error_unit": "m2 (blind spot)",
                "path_grid_time_s": t_grid,
                "path_exact_time_s": t_exact,
                "path_max_abs_dpd": float(err.max()),
                "path_mean_abs_dpd": float(err.mean()),
            }
        )
    return rows


def search_rows(n: int) -> list[dict[str, Any]]:
    """Lookup vs exact, scoped vs full, target bodies vs points, on the same random
    candidates; the reference is exact evaluation of bodies with every sensor (the
    collision probability, and which candidates are sensor-critical)."""
    envs = load_environments()
    env = {e: envs[e] for e in ENVIRONMENTS}
    rows = []
    settings = (
        ("lookup (bodies)", "lookup", True, True),
        ("exact, scene-limited (bodies)", "exact", True, True),
        ("exact, full (bodies)", "exact", False, True),
        ("exact, points (the paper's setting)", "exact", True, False),
    )
    for family in FAMILIES:
        results: dict[str, dict[str, np.ndarray]] = {}
        times: dict[str, float] = {}
        for label, mode, scoped, bodies in settings:
            ev = Evaluator(load_system(SYSTEM), mode, bodies=bodies)
            ev.scoped = scoped
            prob = SearchProblem(load_family(family), env, ev)
            U = np.random.default_rng(1).random((n, prob.dim))
            prob.evaluate_decoded(prob.decode_batch(U[:64]))  # warm-up
            t0 = time.perf_counter()
            out = prob.evaluate_decoded(prob.decode_batch(U))
            times[label] = time.perf_counter() - t0
            results[label] = out.metrics
        base = results["exact, full (bodies)"]
        crit = (base["collision_probability"] > 0) & (base["collision_perfect"] == 0)
        top = set(np.argsort(-base["collision_probability"], kind="stable")[:10].tolist())
        for label, *_ in settings:
            m = results[label]
            d = np.abs(m["collision_probability"] - base["collision_probability"])
            c = (m["collision_probability"] > 0) & (m["collision_perfect"] == 0)
            rows.append(
                {
                    "study": f"search Pd ({family})",
                    "setting": label,
                    "time_s": times[label],
                    "ms_per_candidate": 1e3 * times[label] / n,
                    "error": float(d.max()),
                    "error_unit": "max abs d P(collision) vs exact bodies",
                    "mean_error": float(d.mean()),
                    "class_changes": int(np.sum(c != crit)),
                    "top10_overlap": len(
                        top
                        & set(np.argsort(-m["collision_probability"], kind="stable")[:10].tolist())
                    ),
                }
            )
    return rows


def _figure(rows: list[dict[str, Any]], out: Path) -> None:
    from sensorgap.runtime import pristine_matplotlib

    pristine_matplotlib()
    import matplotlib.pyplot as plt

    res = [r for r in rows if r["study"] == "grid resolution"]
    x = [float(r["setting"].split()[0]) for r in res]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    fig.subplots_adjust(wspace=0.35, bottom=0.16)
    a.loglog(x, [max(r["error"], 1e-6) for r in res], "o-", label="blind-spot area [m2]")
    a.loglog(
        x, [max(r["path_max_abs_dpd"], 1e-9) for r in res], "s-", label="max |dPd| along paths"
    )
    a.set_xlabel("grid resolution [m]")
    a.set_ylabel("error")
    a.legend(fontsize=8)
    b.loglog(x, [r["time_s"] for r in res], "o-", label="near-field grid")
    b.loglog(x, [r["path_grid_time_s"] for r in res], "s-", label="path map (2 threads)")
    b.set_xlabel("grid resolution [m]")
    b.set_ylabel("time [s]")
    b.legend(fontsize=8)
    save_figure(fig, out / "resolution.png", dpi=90)


def run_tradeoff(out: Path, quick: bool = False) -> list[dict[str, Any]]:
    """Measure and write the trade-off tables (``quick``: coarse, for tests)."""
    # every preset and road it uses, before it measures anything (hostile round 28: a
    # SENSORGAP_ROADS lacking the families' road was refused after 15 s of measuring)
    require_shipped(
        vehicles=(SYSTEM,), environments=ENVIRONMENTS, targets=("car",), families=FAMILIES
    )
    for family in FAMILIES:
        load_family(family)
    out.mkdir(parents=True, exist_ok=True)
    rows = resolution_rows(SYSTEM, RESOLUTIONS[:3] if quick else RESOLUTIONS)
    rows += search_rows(200 if quick else 2000)
    cols = [
        "study",
        "setting",
        "time_s",
        "error",
        "error_unit",
        "mean_error",
        "ms_per_candidate",
        "top10_overlap",
        "class_changes",
        "blind_spot_m2",
        "blind_spot_exact_m2",
        "path_grid_time_s",
        "path_exact_time_s",
        "path_max_abs_dpd",
        "path_mean_abs_dpd",
    ]
    atomic_write_bytes(out / "tradeoff.csv", ranking_csv(rows, cols))
    lines = [
        "# Speed vs accuracy (this machine, one run)",
        "",
        "| study | setting | time [s] | error | unit | extra |",
        "|---|---|---|---|---|---|",
    ]
    for r in rows:
        extra = (
            f"path max/mean dPd {r['path_max_abs_dpd']:.2e}/{r['path_mean_abs_dpd']:.2e}"
            if "path_max_abs_dpd" in r
            else f"{r['ms_per_candidate']:.3f} ms/candidate, top-10 overlap "
            f"{r['top10_overlap']}/10, mean error {r['mean_error']:.2e}, "
            f"{r['class_changes']} candidates change class (sensor-critical or not)"
        )
        lines.append(
            f"| {r['study']} | {r['setting']} | {r['time_s']:.3f} | "
            f"{r['error']:.3g} | {r['error_unit']} | {extra} |"
        )
    atomic_write_text(out / "tradeoff.md", "\n".join(lines) + "\n")
    _figure(rows, out)
    write_manifest(out)
    return rows
