"""Corridor search: the least-detectable approach path into a critical zone.

After Ponn, Lanz & Diermeyer (2020), who search the path the sensors perceive worst with A*
on the coverage map. Here, in the ego's vehicle frame (the ego's sensors move with it, so a
path is relative motion), a lattice over the coverage map:

* nodes: points at the target's reference height, one column per sensor cycle and rows
  ``lateral_res`` apart that lie on a lane band (``lanes``: lateral intervals in the
  vehicle frame, m), with the exact fused Pd at each;
* edges: from column i to column i + 1 (one sensor cycle, ``step = v_rel * dt``), lateral
  moves of at most ``max_lateral_cells`` rows per column, which bounds the relative heading
  (kinematics) and the lateral speed ``<= max_lateral_cells * res / dt``;
* cost of entering a cell: ``-ln(1 - Pd)``, the negative log of the probability that the
  sensor cycle there misses the target (per-cycle independence, as the search metrics), so
  the shortest path maximises ``P_undet = exp(-sum cost)`` over the whole approach;
* no node where the target's footprint (its length along x, its width across, centred on
  the node) overlaps the ego's body: a path cannot run through the vehicle itself (lane
  bands across the ego, ``--lanes -1:1``, were searched through it). Where every path
  would, the search is refused.

The path runs from the start column (``x_start``) to the critical zone (``x_goal``; e.g.
just ahead of the ego's front bumper for an overtaking target). The networkx shortest path
(Dijkstra with a virtual source and sink) is returned as a time-sampled trajectory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import networkx as nx
import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.scene import Scene
from sensorgap.errors import InputError

F64 = NDArray[np.float64]
#: Cost of a cell where the target is detected with certainty (Pd = 1): -ln(1e-300).
CERTAIN_COST = -math.log(1e-300)
#: Input limits (docs/limits.md): lattice nodes (~1 kB each in the graph), start/goal x and
#: lane bands, m.
MAX_CORRIDOR_NODES = 500_000
MAX_CORRIDOR_X_M = 2_000.0
MAX_CORRIDOR_Y_M = 200.0
#: Largest relative speed along x, m/s: the bound of every speed difference
#: (``config.parameters.SUFFIX_BOUNDS``, ``*_m_s``); beyond it a lattice column lies
#: kilometres past the goal (1e308 m/s overflowed in the sensor kernel).
MAX_CORRIDOR_SPEED_M_S = 100.0


@dataclass(frozen=True)
class Corridor:
    """The least-detectable path (vehicle frame) and what it achieves.

    Attributes:
        t: time, s. x, y: position of the target's reference point, m. heading: rad.
        pd: per-cycle detection probability along the path.
        p_undetected: probability the target is never detected along the whole path.
        log10_p_undetected: the same in the log domain (stays graded where it underflows).
        speed_rel: relative speed along x, m/s.
    """

    t: F64
    x: F64
    y: F64
    heading: F64
    pd: F64
    p_undetected: float
    log10_p_undetected: float
    speed_rel: float


def _count(n: float) -> str:
    """A lattice dimension as the whole number of nodes it needs (rounded up), written in
    full: rounded to 3 digits a count just beyond the limit read as the limit itself. From
    1e15 on (far beyond any limit) it is "about 1.32e+302": ``--speed 1e-300`` quoted a
    405-digit count (remark of session 25)."""
    if not math.isfinite(n):
        return "infinitely many"
    return f"{math.ceil(n):,}" if n < 1e15 else f"about {n:.3g}"


def corridor_search(
    scene: Scene,
    x_start: float,
    x_goal: float,
    lanes: list[tuple[float, float]],
    speed_rel: float,
    dt: float = 0.05,
    lateral_res: float = 0.25,
    max_lateral_cells: int = 1,
    height: float | None = None,
) -> Corridor:
    """Least-detectable path from ``x_start`` to ``x_goal`` (vehicle frame, m) on ``lanes``.

    Args:
        speed_rel: relative speed of the target along x, m/s (> 0: moving towards +x).
        dt: sensor cycle, s (one column per cycle: column spacing ``speed_rel * dt``).
        lateral_res: row spacing, m. max_lateral_cells: rows per cycle at most.
    """
    if not (math.isfinite(speed_rel) and 0.0 < speed_rel <= MAX_CORRIDOR_SPEED_M_S):
        raise InputError(
            "speed",
            "",
            f"relative speed must be > 0 and <= {MAX_CORRIDOR_SPEED_M_S:g} m/s, got {speed_rel!r}",
        )
    if not x_goal > x_start:
        raise InputError(
            "goal",
            "",
            f"goal x ({x_goal:g}) must lie ahead of start x "
            f"({x_start:g}) in the direction of motion",
        )
    if not lanes or any(not (lo < hi) for lo, hi in lanes):
        raise InputError("lanes", "", "need at least one lateral interval lo < hi (m)")
    if max(abs(x_start), abs(x_goal)) > MAX_CORRIDOR_X_M:
        raise InputError(
            "corridor",
            "x_start/x_goal",
            f"must be within +-{MAX_CORRIDOR_X_M:g} m, got {x_start:g} and {x_goal:g}",
        )
    if any(max(abs(lo), abs(hi)) > MAX_CORRIDOR_Y_M for lo, hi in lanes):
        raise InputError(
            "corridor", "lanes", f"lane bands must lie within +-{MAX_CORRIDOR_Y_M:g} m of the ego"
        )
    if not (math.isfinite(lateral_res) and lateral_res > 0.0):
        raise InputError("corridor", "lateral_res", f"must be > 0 m, got {lateral_res!r}")
    step = speed_rel * dt
    y_lo, y_hi = min(lo for lo, _ in lanes), max(hi for _, hi in lanes)
    # the lattice size before anything is allocated (a graph node costs ~1 kB)
    # a subnormal speed makes the step 0 (hostile round eighteen, F3: ZeroDivisionError)
    cols_est = (x_goal - x_start) / step + 1.0 if step > 0.0 else math.inf
    rows_est = (y_hi - y_lo) / lateral_res + 1.0
    if cols_est > MAX_CORRIDOR_NODES:  # too many columns even for a single row
        raise InputError(
            "corridor",
            "speed_rel",
            f"{_count(cols_est)} columns of the lattice (one per {dt:g} s over "
            f"{abs(x_goal - x_start):g} m at {speed_rel!r} m/s) are too many (at most "
            f"{MAX_CORRIDOR_NODES:,} nodes); raise the speed or shorten the approach",
        )
    if cols_est * rows_est > MAX_CORRIDOR_NODES:
        raise InputError(
            "corridor",
            "lateral_res",
            f"a lattice of {_count(cols_est)} columns x "
            f"{_count(rows_est)} rows is too large (at most {MAX_CORRIDOR_NODES:,} "
            "nodes); coarsen the lateral resolution, shorten the approach or "
            "raise the speed",
        )
    n_cols = max(2, round((x_goal - x_start) / step) + 1)
    h = scene.target.reference_height_m if height is None else height
    # columns at the cycle spacing, rows at lateral_res: the exact fused Pd per node
    xs = np.asarray(x_start + np.arange(n_cols) * step, dtype=np.float64)
    ys = np.asarray(np.arange(y_lo + 0.5 * lateral_res, y_hi, lateral_res), dtype=np.float64)
    on_lane = np.zeros(ys.size, dtype=bool)
    for lo, hi in lanes:
        on_lane |= (ys >= lo) & (ys <= hi)
    if not on_lane.any():
        raise InputError("lanes", "", f"no row of {lateral_res:g} m fits the lanes")
    rows = np.flatnonzero(on_lane)
    inside = _inside_body(scene, xs, ys[rows])
    if _blocked(inside):
        raise _through_body(scene, x_start, x_goal)
    pd = _pd_nodes(scene, xs, ys[rows], h)
    with np.errstate(divide="ignore"):
        cost = np.where(pd >= 1.0, CERTAIN_COST, -np.log1p(-np.minimum(pd, 1.0)))
    g = nx.DiGraph()
    for r in range(rows.size):
        if not inside[0, r]:
            g.add_edge("source", (0, r), weight=float(cost[0, r]))
        g.add_edge((n_cols - 1, r), "sink", weight=0.0)
    for c in range(n_cols - 1):
        for r in range(rows.size):
            for dr in range(-max_lateral_cells, max_lateral_cells + 1):
                r2 = r + dr
                # stay on the lattice, do not jump across a gap between lane bands, never
                # enter the ego's body
                if (
                    0 <= r2 < rows.size
                    and abs(int(rows[r2]) - int(rows[r])) == abs(dr)
                    and not inside[c + 1, r2]
                ):
                    g.add_edge((c, r), (c + 1, r2), weight=float(cost[c + 1, r2]))
    try:
        path = nx.shortest_path(g, "source", "sink", weight="weight")[1:-1]
    except nx.NetworkXNoPath:  # the body leaves gaps that no lateral move can reach
        raise _through_body(scene, x_start, x_goal) from None
    cols = np.array([p[0] for p in path])
    rr = np.array([p[1] for p in path])
    x, y = xs[cols], ys[rows[rr]]
    heading = np.arctan2(np.gradient(y), np.gradient(x))
    pd_path = pd[cols, rr]
    total = float(np.sum(cost[cols, rr]))
    return Corridor(
        t=cols * dt,
        x=x,
        y=y,
        heading=heading,
        pd=pd_path,
        p_undetected=math.exp(-total),
        log10_p_undetected=-total / math.log(10.0) + 0.0,  # + 0.0: never -0.0 (certain)
        speed_rel=speed_rel,
    )


def _inside_body(scene: Scene, xs: F64, ys: F64) -> NDArray[np.bool_]:
    """(columns, rows): the target centred at (``xs[i]``, ``ys[j]``) (m, vehicle frame,
    heading along x) overlaps the ego's body box."""
    body = scene.system.config.vehicle
    half_l, half_w = 0.5 * scene.target.length_m, 0.5 * scene.target.width_m
    in_x = (xs > body.x_rear_m - half_l) & (xs < body.x_front_m + half_l)
    in_y = np.abs(ys) < 0.5 * body.width_m + half_w
    return np.asarray(in_x[:, None] & in_y[None, :], dtype=bool)


def _through_body(scene: Scene, x_start: float, x_goal: float) -> InputError:
    """The refusal of lane bands that lead every path into the ego's body."""
    body = scene.system.config.vehicle
    return InputError(
        "corridor",
        "lanes",
        f"every path from x {x_start:g} to {x_goal:g} m on these bands runs into the "
        f"vehicle's own body (x {body.x_rear_m:g} to {body.x_front_m:g} m, y within "
        f"+-{0.5 * body.width_m:g} m, widened by the {scene.target.name}'s size); "
        "choose bands beside it",
    )


def _blocked(inside: NDArray[np.bool_]) -> bool:
    """Some column lies wholly inside the body (every row of it), so no path passes."""
    return bool(inside.all(axis=1).any())


def _pd_nodes(scene: Scene, xs: F64, ys: F64, height: float) -> F64:
    """Exact fused Pd at every lattice node, (columns, rows)."""
    from sensorgap.coverage.points import evaluate_points

    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel(), np.full(X.size, height)])
    return evaluate_points(scene, pts).fused.reshape(X.shape)


__all__ = ["CERTAIN_COST", "Corridor", "corridor_search"]
