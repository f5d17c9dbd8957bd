"""Issue 2 benchmark: System A, car, clear, 0.75 m, 0.1 m grid over x -100..300, y -30..30
(2.4 M cells). sensorgap's tiled/culled/threaded grid vs a straightforward numpy
evaluation (every sensor on every cell, full-size arrays, eq. 11 as a running product),
max |delta Pd| between the two, time and peak memory. Targets: <= 0.2 s on 2 cores,
>= 15x faster than the straightforward one, max |delta Pd| <= 1e-9."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from benchmarks.common import max_rss_mib, measure, table
from sensorgap.config import load_environment, load_target
from sensorgap.coverage import GridSpec, Scene, evaluate_grid
from sensorgap.models import Conditions, load_system
from sensorgap.models.geometry import in_range, rotate_offsets, spherical
from sensorgap.models.roc import detection_probability

GRID = GridSpec(-100.0, 300.0, -30.0, 30.0, 0.1, 0.75)


def straightforward(scene: Scene, grid: GridSpec) -> NDArray[np.float64]:
    """Every sensor on every cell; FOV by the angle definition; fusion as a product."""
    X, Y = np.meshgrid(grid.xs(), grid.ys())
    miss = np.ones_like(X)
    for s in scene.sensors:
        m = s.mount
        xs, ys, zs = rotate_offsets(m, X - m.x, Y - m.y, grid.height - m.z)
        r, az, el = spherical(xs, ys, zs)
        ok = in_range(m, r) & (np.abs(az) <= 0.5 * m.hfov) & (np.abs(el) <= 0.5 * m.vfov)
        pd = np.zeros_like(X)
        snr = scene.prepared(s).snr_db(r[ok], az[ok], el[ok])
        pd[ok] = detection_probability(snr, s.roc, scene.roc_shift_db)
        miss *= 1.0 - pd
    return 1.0 - miss


def run() -> str:
    """Run the benchmark; returns the Markdown table."""
    scene = Scene(
        load_system("system_a"),
        load_target("car"),
        Conditions.from_config(load_environment("clear")),
    )
    t_ref, mem_ref, ref = measure(lambda: straightforward(scene, GRID), repeat=2)
    rows = []
    for workers in (1, 2):
        t, mem, cov = measure(lambda w=workers: evaluate_grid(scene, GRID, workers=w))
        delta = float(np.max(np.abs(cov.fused - ref)))
        rows.append(
            [
                f"sensorgap grid, {workers} thread(s)",
                f"{t:.3f}",
                f"{t_ref / t:.1f}x",
                f"{delta:.1e}",
                f"{mem:.0f}",
                "<= 0.2 s, >= 15x, <= 1e-9" if workers == 2 else "",
            ]
        )
    rows.insert(
        0, ["straightforward numpy", f"{t_ref:.3f}", "1.0x", "0 (reference)", f"{mem_ref:.0f}", ""]
    )
    head = (
        f"Coverage map: System A, car, clear, h = 0.75 m, {GRID.nx} x {GRID.ny} = "
        f"{GRID.cells:,} cells at {GRID.resolution} m\n\n"
    )
    return (
        head
        + table(["method", "time [s]", "speed-up", "max |dPd|", "peak mem [MiB]", "target"], rows)
        + f"\n\nprocess peak RSS: {max_rss_mib():.0f} MiB\n"
    )


if __name__ == "__main__":
    print(run())
