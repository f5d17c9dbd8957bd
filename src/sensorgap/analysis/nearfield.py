"""Near-field analysis (Ponn 2019 Sec. IV-A, Fig. 5): blind spots around the vehicle.

Only the geometric "sensor coverage" step of the paper (field of view and range, no SNR):

* **any-height footprint** of a sensor: the horizontal points (x, y) for which *some* height
  z in the object height range ``[h_lo, h_hi]`` (default 0..4 m) puts (x, y, z) inside the
  sensor's field of view and range;
* **blind spots** (Fig. 5 blue): the bounded regions outside the vehicle footprint that no
  sensor sees at any height, i.e. the holes of the union of all any-height footprints and the
  vehicle footprint (inside the near-field window);
* **uncovered at 0.1 m** (Fig. 5 green): the part of the near-field window, outside the
  vehicle footprint, that no sensor sees at the minimal object height of 0.1 m.

Exact method: each footprint is a polar region around the mount, ``rho in I(phi)`` for the
horizontal direction ``phi``. In the vertical half-plane at ``phi`` the field of view is a
set of rays (elevation angles ``theta``) whose end points are found in closed form (the
azimuth planes and elevation cones of ``fov_mask`` meet the half-plane in rays); range and
height bounds then give ``I(phi)`` in closed form. The boundary is sampled every
``dphi_deg`` (0.1 deg) with every structural change (a ray interval or a rho interval
appearing or vanishing) located to 1e-12 rad by repeated sectioning, and refined where it
bends faster than the sampling, so the only error is the chord of the sampled arcs
(relative area error ~dphi^2/6, about 5e-7; measured in docs/nearfield.md).

Grid method: cell centres classified with ``rotate_offsets``, ``fov_mask`` and ``in_range``
at sampled heights (spacing <= the cell size, plus the height range's ends and every mount
height); blind spots are the 4-connected components of unseen cells that do not touch the
grid border.

Not modelled (as in the paper): occlusion by the vehicle body or by other objects.
"""

from __future__ import annotations

import copy
import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from dataclasses import astuple, dataclass
from itertools import islice, repeat
from operator import itemgetter
from pathlib import Path
from typing import Any, NamedTuple, TypeAlias

import numpy as np
import shapely
from numpy.typing import NDArray
from shapely.geometry import MultiPolygon, Polygon, box
from shapely.geometry.base import BaseGeometry

from sensorgap.errors import InputError
from sensorgap.filesio import write_json
from sensorgap.models.geometry import Mount, fov_mask, in_range, rotate_offsets
from sensorgap.models.system import Sensor, System

F64 = NDArray[np.float64]
IntArr = NDArray[np.intp]
Area: TypeAlias = Polygon | MultiPolygon

#: Heights an object ("road user") may occupy, m: from the ground to 4 m (EU maximum vehicle
#: height, Directive 96/53/EC). See docs/nearfield.md for the sensitivity to this choice.
HEIGHT_RANGE_M: tuple[float, float] = (0.0, 4.0)
#: The paper's minimal object height, m (Fig. 5 green).
MIN_OBJECT_HEIGHT_M = 0.1
#: Near-field window: the vehicle footprint rectangle grown by this margin on every side, m.
NEAR_FIELD_RADIUS_M = 5.0
#: Angular sampling of footprint boundaries, deg.
DPHI_DEG = 0.1
#: Coordinates of the polygon overlays are snapped to this grid, m (removes seam slivers).
SNAP_M = 1e-9
#: Footprint boundaries are refined until no sample deviates from the chord of its
#: neighbours by more than this (m) plus ``REFINE_TOL_REL`` x its distance from the mount.
REFINE_TOL_M = 1e-5
REFINE_TOL_REL = 1e-6
#: Holes smaller than this are seam slivers of the overlay, not blind spots, m2.
MIN_HOLE_M2 = 1e-6

_HALF_PI = 0.5 * math.pi
_BISECT_TOL = 1e-12
_SECTIONS = 32

Interval = tuple[float, float]
Signature = tuple[int, int]


# --------------------------------------------------------------------------- exact footprints


def _mount(sensor: Sensor | Mount) -> Mount:
    return sensor.mount if isinstance(sensor, Sensor) else sensor


def _check_heights(m: Mount, height_range: tuple[float, float]) -> tuple[float, float]:
    lo, hi = (float(height_range[0]), float(height_range[1]))
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise ValueError(f"height range must be finite with lo <= hi, got {height_range!r}")
    if not (lo <= m.z <= hi):
        raise ValueError(
            f"mount height {m.z:g} m lies outside the object height range "
            f"{lo:g}..{hi:g} m; widen height_range"
        )
    return lo, hi


def _wrap_half(t: F64) -> F64:
    """Angles (rad) folded by +-pi into [-pi/2, pi/2] (roots of a*cos + b*sin = 0)."""
    t = np.where(t > _HALF_PI, t - math.pi, t)
    return np.where(t < -_HALF_PI, t + math.pi, t)


def _theta_candidates(m: Mount, phis: F64, t_lo: float, t_hi: float) -> F64:
    """Elevations (rad, sorted, within [t_lo, t_hi]) where, in the vertical half-plane at
    horizontal direction ``phi``, a ray may enter or leave the field of view: the rays in
    which the azimuth planes and the elevation cones of ``fov_mask`` cut the half-plane."""
    c, s = np.cos(phis), np.sin(phis)
    zero = np.zeros_like(phis)
    ax, ay, az = rotate_offsets(m, c, s, 0.0)  # horizontal unit vector, sensor frame
    bx, by, bz = rotate_offsets(m, zero, zero, 1.0)  # vertical unit vector, sensor frame
    cands = [np.full_like(phis, t_lo), np.full_like(phis, t_hi)]

    def linear_root(p: F64, q: F64) -> None:
        # p cos(t) + q sin(t) = 0 (a plane through the mount cuts the half-plane in a ray)
        cands.append(_wrap_half(np.arctan2(-p, q)))

    half_h = 0.5 * m.hfov
    if half_h < math.pi:
        linear_root(ax, bx)
        linear_root(ay, by)
        if half_h != _HALF_PI:
            tt = math.tan(half_h) if half_h < _HALF_PI else math.tan(math.pi - half_h)
            linear_root(tt * ax - ay, tt * bx - by)
            linear_root(tt * ax + ay, tt * bx + by)
    half_v = 0.5 * m.vfov
    if half_v < _HALF_PI:
        # the sensor-frame z of the unit ray is A cos(t - alpha); |z| = sin(vfov/2) on the cone
        amp = np.hypot(az, bz)
        alpha = np.arctan2(bz, az)
        sv = math.sin(half_v)
        safe = np.where(amp > 1e-300, amp, 1.0)
        for sign in (1.0, -1.0):
            ratio = sign * sv / safe
            ok = (amp > 1e-300) & (np.abs(ratio) <= 1.0)
            acos = np.arccos(np.clip(ratio, -1.0, 1.0))
            for root in (alpha + acos, alpha - acos):
                r = np.remainder(root + math.pi, 2.0 * math.pi) - math.pi
                cands.append(np.where(ok & (np.abs(r) <= _HALF_PI), r, t_lo))
    out = np.clip(np.stack(cands, axis=1), t_lo, t_hi)
    return np.sort(out, axis=1)


def _theta_pieces(
    m: Mount, phis: F64, t_lo: float, t_hi: float
) -> tuple[F64, F64, NDArray[np.bool_]]:
    """Elementary elevation intervals per direction and whether each is in view."""
    cand = _theta_candidates(m, phis, t_lo, t_hi)
    t1, t2 = cand[:, :-1], cand[:, 1:]
    mid = 0.5 * (t1 + t2)
    ph = np.broadcast_to(phis[:, None], mid.shape)
    cm = np.cos(mid)
    xs, ys, zs = rotate_offsets(m, cm * np.cos(ph), cm * np.sin(ph), np.sin(mid))
    valid = fov_mask(m, xs, ys, zs) & (t2 > t1)
    return t1, t2, valid


def _components(t1: F64, t2: F64, valid: NDArray[np.bool_]) -> tuple[F64, F64, IntArr, IntArr]:
    """The maximal runs of in-view elementary intervals of every direction (row; zero-width
    pieces are transparent): (start of each run's first piece, end of its last piece, the
    run's row, the number of runs per row), runs in row order. A run starts at an in-view
    piece whose kept predecessor in its row is not in view, and ends likewise."""
    n, k = t1.shape
    idx = np.flatnonzero(~(t2 <= t1).ravel())  # kept pieces, row by row
    row = idx // k
    v = valid.ravel()[idx]
    same = row[1:] == row[:-1]
    start = v.copy()
    start[1:] &= ~(same & v[:-1])
    end = v.copy()
    end[:-1] &= ~(same & v[1:])
    runs = row[start]
    return t1.ravel()[idx[start]], t2.ravel()[idx[end]], runs, np.bincount(runs, minlength=n)


def _merge(ivs: list[Interval]) -> list[Interval]:
    out: list[Interval] = []
    for a, b in sorted(ivs):
        if out and a <= out[-1][1]:
            out[-1] = (out[-1][0], max(out[-1][1], b))
        else:
            out.append((a, b))
    return out


def _per_direction(
    lo: F64, hi: F64, rows: IntArr, n_runs: IntArr
) -> tuple[list[list[Interval]], list[Signature]]:
    """rho intervals ``(lo, hi)`` (in row order, ``rows``: the direction of each) as merged
    lists per direction, and each direction's signature (runs, merged intervals)."""
    counts = np.bincount(rows, minlength=n_runs.size)
    it = iter(zip(lo.tolist(), hi.tolist(), strict=True))
    # each direction's list: the next counts[i] intervals (no Python loop per direction)
    ivs_all: list[list[Interval]] = list(map(list, map(islice, repeat(it), counts.tolist())))
    for i in np.flatnonzero(counts > 1).tolist():
        ivs_all[i] = _merge(ivs_all[i])
        counts[i] = len(ivs_all[i])
    return ivs_all, list(zip(n_runs.tolist(), counts.tolist(), strict=True))


PolarFn = Callable[[F64], tuple[list[list[Interval]], list[Signature]]]


def _any_height_fn(m: Mount, h_lo: float, h_hi: float) -> PolarFn:
    """rho intervals (m) per direction of the points seen at some height in [h_lo, h_hi]."""
    down, up = m.z - h_lo, h_hi - m.z  # >= 0
    rmin, rmax = m.min_range, m.max_range
    # a ray at elevation t reaches r_hi(t) = min(rmax, height bound); it holds a point in
    # range iff r_hi(t) >= rmin
    t_lo = -math.asin(min(1.0, down / rmin)) if rmin > 0.0 else -_HALF_PI
    t_hi = math.asin(min(1.0, up / rmin)) if rmin > 0.0 else _HALF_PI

    def r_hi_cos(t: F64) -> F64:
        r = np.full(t.shape, rmax)
        st = np.sin(t)
        for side, s, h in ((t < 0.0, -st, down), (t > 0.0, st, up)):
            near = side & (h < rmax * s)  # the height bound comes first
            r[near] = np.minimum(rmax, h / s[near])
        return np.asarray(r * np.cos(t), dtype=np.float64)

    def fn(phis: F64) -> tuple[list[list[Interval]], list[Signature]]:
        if t_lo == t_hi == 0.0 or rmax <= rmin:
            return [[] for _ in phis], [(0, 0) for _ in phis]
        a, b, rows, n_runs = _components(*_theta_pieces(m, phis, t_lo, t_hi))
        t_star = np.minimum(np.maximum(0.0, a), b)  # r_hi(t) cos t decreases with |t|
        lo = rmin * np.minimum(np.cos(a), np.cos(b))
        return _per_direction(lo, r_hi_cos(t_star), rows, n_runs)

    return fn


def _at_height_fn(m: Mount, z: float) -> PolarFn:
    """rho intervals (m) per direction of the points at height z in view and in range."""
    dz = z - m.z
    rmin, rmax = m.min_range, m.max_range
    empty = abs(dz) > rmax
    rho_a = math.sqrt(max(rmin * rmin - dz * dz, 0.0))
    rho_b = math.sqrt(max(rmax * rmax - dz * dz, 0.0))

    def rho_of(a: F64, b: F64) -> tuple[NDArray[np.bool_], F64, F64]:
        # the horizontal line at height dz meets the rays t in [a, b] at rho = dz / tan(t):
        # (which ray intervals meet it in range, rho from, rho to)
        lo, hi = np.zeros_like(a), np.full_like(a, math.inf)
        with np.errstate(over="ignore"):  # a ray just above the horizon: rho = inf
            if dz > 0.0:
                ok = ~(b <= 0.0)
                lo[ok] = dz * np.cos(b[ok]) / np.sin(b[ok])
                up = ok & ~(a <= 0.0)
                hi[up] = dz * np.cos(a[up]) / np.sin(a[up])
            elif dz < 0.0:
                ok = ~(a >= 0.0)
                lo[ok] = -dz * np.cos(a[ok]) / -np.sin(a[ok])
                down = ok & ~(b >= 0.0)
                hi[down] = -dz * np.cos(b[down]) / -np.sin(b[down])
            else:
                ok = (a <= 0.0) & (b >= 0.0)
        lo, hi = np.maximum(lo, rho_a), np.minimum(hi, rho_b)
        return ok & (hi > lo), lo, hi

    def fn(phis: F64) -> tuple[list[list[Interval]], list[Signature]]:
        if empty:
            return [[] for _ in phis], [(0, 0) for _ in phis]
        a, b, rows, n_runs = _components(*_theta_pieces(m, phis, -_HALF_PI, _HALF_PI))
        ok, lo, hi = rho_of(a, b)
        return _per_direction(lo[ok], hi[ok], rows[ok], n_runs)

    return fn


def _polar_region(m: Mount, fn: PolarFn, dphi_deg: float) -> Area:
    """The polygon {mount + rho (cos phi, sin phi): rho in I(phi)} from a sampled boundary.

    Directions are sampled every ``dphi_deg`` starting behind the sensor; wherever the
    structure of I(phi) changes between two samples the change is located (to 1e-12 rad) and
    the region is split there, so radial edges are exact. Pieces are also split every
    90 deg so that no piece wraps around the mount. Within a piece, samples are added where
    the boundary bends faster than the sampling (``_refine``).
    """
    if not (0.0 < dphi_deg <= 5.0):
        raise ValueError(f"dphi_deg must be in (0, 5], got {dphi_deg!r}")
    n = 4 * math.ceil(90.0 / dphi_deg)
    phi0 = m.yaw + math.pi
    phis = phi0 + np.arange(n + 1, dtype=np.float64) * (2.0 * math.pi / n)
    ivs, sigs = fn(phis)

    pieces: list[list[tuple[float, list[Interval]]]] = []
    cur: list[tuple[float, list[Interval]]] = []
    cur_sig = sigs[0]
    phi_l = phis.tolist()
    quarter = n // 4
    # the samples where the structure changes or a quarter ends; the samples between two of
    # them join the current piece as they are
    sig_arr = np.array(sigs)
    changed = np.flatnonzero(np.any(sig_arr[1:] != sig_arr[:-1], axis=1)) + 1
    done = 0
    for i in sorted(set(changed.tolist()).union(range(quarter, n + 1, quarter))):
        cur.extend(zip(phi_l[done:i], ivs[done:i], strict=True))
        phi, iv, sg = phi_l[i], ivs[i], sigs[i]
        left_phi, left_iv = phi_l[i - 1], ivs[i - 1]
        while sg != cur_sig:
            lo, hi = left_phi, phi
            lo_iv, hi_iv, hi_sig = left_iv, iv, sg
            while hi - lo > _BISECT_TOL:
                # multisection: the first sample whose structure differs from cur_sig
                grid = np.linspace(lo, hi, _SECTIONS + 1)
                g_iv, g_sig = fn(grid[1:-1])
                k = next((j for j, sg_j in enumerate(g_sig) if sg_j != cur_sig), None)
                if k is None:
                    lo, lo_iv = float(grid[-2]), g_iv[-1]
                else:
                    hi, hi_iv, hi_sig = float(grid[k + 1]), g_iv[k], g_sig[k]
                    if k > 0:
                        lo, lo_iv = float(grid[k]), g_iv[k - 1]
            brk = 0.5 * (lo + hi)
            cur.append((brk, lo_iv))
            pieces.append(cur)
            cur = [(brk, hi_iv)]
            cur_sig = hi_sig
            left_phi, left_iv = hi, hi_iv
        cur.append((phi, iv))
        if i % quarter == 0:
            pieces.append(cur)
            cur = [(phi, iv)]
        done = i + 1
    cur.extend(zip(phi_l[done:], ivs[done:], strict=True))
    pieces.append(cur)

    polys: list[Polygon] = []
    for piece in pieces:
        k = len(piece[0][1])
        if k == 0 or len(piece) < 2:
            continue
        piece = _refine(fn, piece, math.radians(dphi_deg))
        ph = np.array(list(map(itemgetter(0), piece)), dtype=np.float64)
        r = np.array(list(map(itemgetter(1), piece)), dtype=np.float64)  # (samples, k, 2)
        cx, cy = np.cos(ph), np.sin(ph)
        for j in range(k):
            lo_r, hi_r = r[:, j, 0], r[:, j, 1]
            ring = np.concatenate(
                [
                    np.column_stack([m.x + hi_r * cx, m.y + hi_r * cy]),
                    np.column_stack([m.x + lo_r * cx, m.y + lo_r * cy])[::-1],
                ]
            )
            poly = Polygon(ring)
            if not poly.is_valid:
                poly = shapely.make_valid(poly)
            polys.append(poly)
    return _as_area(shapely.union_all(polys, grid_size=SNAP_M)) if polys else Polygon()


def _boundary_points(phis: list[float], ivs: list[list[Interval]]) -> F64:
    """Boundary points (N, 2k, 2) relative to the mount of k rho intervals at N directions."""
    ph = np.asarray(phis, dtype=np.float64)[:, None]
    r = np.asarray(ivs, dtype=np.float64).reshape(len(phis), -1)
    return np.stack([r * np.cos(ph), r * np.sin(ph)], axis=-1)


def _deviation_excess(a: F64, b: F64, p: F64, rel: float) -> F64:
    """Excess of the distance of points ``p`` from the segments a-b over the tolerance
    ``REFINE_TOL_M + rel * |p|`` (m; points relative to the mount), maximised over the
    second-last axis; > 0 means refine. Arrays (..., n, 2)."""
    ab = b - a
    den = np.sum(ab * ab, axis=-1)
    t = np.clip(np.sum((p - a) * ab, axis=-1) / np.where(den > 0.0, den, 1.0), 0.0, 1.0)
    d = p - (a + t[..., None] * ab)
    dist = np.sqrt(d[..., 0] ** 2 + d[..., 1] ** 2)
    tol = REFINE_TOL_M + rel * np.sqrt(p[..., 0] ** 2 + p[..., 1] ** 2)
    return np.asarray(np.max(dist - tol, axis=-1), dtype=np.float64)


def _refine(
    fn: PolarFn, piece: list[tuple[float, list[Interval]]], dphi: float
) -> list[tuple[float, list[Interval]]]:
    """Insert directions into a piece (constant structure) until no sampled boundary point
    deviates from the chord of its neighbours by more than ``REFINE_TOL_M`` + ``rel`` x its
    distance from the mount, ``rel = max(REFINE_TOL_REL, dphi^2 / 4)`` (twice the relative
    sag of an arc's chord at the base step, so arcs are not refined). Steep stretches of
    rho(phi) (a tilted field-of-view plane sweeping through all heights within a fraction
    of a degree) would otherwise be cut short by one chord. A midpoint whose number of
    rho intervals differs from the piece's is not inserted."""
    k = len(piece[0][1])
    rel = max(REFINE_TOL_REL, 0.25 * dphi * dphi)
    order = list(map(itemgetter(0), piece))
    arr = _boundary_points(order, list(map(itemgetter(1), piece)))
    pts = dict(zip(order, arr, strict=True))
    data = dict(piece)
    cand: set[tuple[float, float]] = set()
    if len(order) == 2:
        cand.add((order[0], order[1]))
    else:
        # each sample against the chord of its neighbours; a chord over two steps sags 4x
        # a smooth curve's chord over one step
        a, b, p = arr[:-2], arr[2:], arr[1:-1]
        c = 0.5 * (a + b)
        bad = _deviation_excess(a, b, c + 0.25 * (p - c), rel) > 0.0
        for i in np.flatnonzero(bad).tolist():
            cand.update({(order[i], order[i + 1]), (order[i + 1], order[i + 2])})
    for _ in range(60):
        todo = sorted(c for c in cand if c[1] - c[0] > 1e-10)
        if not todo:
            break
        mids = [0.5 * (lo + hi) for lo, hi in todo]
        m_iv, _ = fn(np.array(mids))
        keep = [i for i, iv in enumerate(m_iv) if len(iv) == k]
        cand = set()
        if not keep:
            break
        p = _boundary_points([mids[i] for i in keep], [m_iv[i] for i in keep])
        a = np.stack([pts[todo[i][0]] for i in keep])
        b = np.stack([pts[todo[i][1]] for i in keep])
        excess = _deviation_excess(a, b, p, rel)
        for j, i in enumerate(keep):
            if excess[j] > 0.0:
                lo, hi = todo[i]
                pts[mids[i]], data[mids[i]] = p[j], m_iv[i]
                cand.update({(lo, mids[i]), (mids[i], hi)})
    return sorted(data.items())


def _as_area(g: BaseGeometry) -> Area:
    """Keep the polygonal part of an overlay result."""
    if isinstance(g, Polygon | MultiPolygon):
        return g
    parts = [p for p in getattr(g, "geoms", []) if isinstance(p, Polygon | MultiPolygon)]
    if not parts:
        return Polygon()
    u = shapely.union_all(parts, grid_size=SNAP_M)
    return u if isinstance(u, Polygon | MultiPolygon) else Polygon()


def sensor_footprint_any_height(
    sensor: Sensor | Mount,
    height_range: tuple[float, float] = HEIGHT_RANGE_M,
    dphi_deg: float = DPHI_DEG,
) -> Area:
    """Horizontal region (vehicle frame, m) the sensor sees at some height in
    ``height_range`` (field of view and range only, no SNR).

    For an unpitched sensor this is the annular sector over yaw +- hfov/2 between
    ``min_range * cos(vfov/2)`` (the minimum range reached along the steepest ray that
    stays within the height range) and ``max_range``. Usually a ``Polygon``; a
    ``MultiPolygon`` if the region falls apart. Raises ``ValueError`` if the mount lies
    outside the height range.
    """
    m = _mount(sensor)
    lo, hi = _check_heights(m, height_range)
    return _footprint(m, ("any", lo, hi), float(dphi_deg))


def sensor_footprint_at_height(
    sensor: Sensor | Mount, z: float, dphi_deg: float = DPHI_DEG
) -> Area:
    """Horizontal region (vehicle frame, m) of the points at height ``z`` (m) inside the
    sensor's field of view and range.

    E.g. an unpitched camera at 1.3 m with vfov 28 deg sees the plane z = 0.1 m only from
    ``(1.3 - 0.1) / tan(14 deg)`` outwards.
    """
    if not math.isfinite(z):
        raise ValueError(f"height must be finite, got {z!r}")
    m = _mount(sensor)
    return _footprint(m, ("at", float(z)), float(dphi_deg))


#: Footprints kept for a later call with the same mount (a job and a comparison draw the
#: near field of one vehicle again): at most this many, least recently used dropped first.
#: One has up to ~3,800 vertices (System A and B), about 0.1 MB: at most ~25 MB in all.
FOOTPRINT_MEMO = 256


class _Memo(OrderedDict[tuple[str, ...], Any]):
    """Results by key, at most ``limit()`` (read at each store: a module constant that
    can be changed), least recently used dropped first."""

    def __init__(self, limit: Callable[[], int]) -> None:
        super().__init__()
        self.limit = limit

    def recall(self, key: tuple[str, ...]) -> Any:
        """The result stored for ``key`` (now the most recently used), else None."""
        hit = self.get(key)
        if hit is not None:
            self.move_to_end(key)
        return hit

    def keep(self, key: tuple[str, ...], value: Any) -> Any:
        """Store ``value`` for ``key``; return it."""
        self[key] = value
        while len(self) > self.limit():
            self.popitem(last=False)
        return value


_memo = _Memo(lambda: FOOTPRINT_MEMO)


def _footprint(m: Mount, kind: tuple[str | float, ...], dphi_deg: float) -> Area:
    """``_polar_region`` of mount ``m`` for ``kind`` (("any", lo, hi) or ("at", z), m),
    computed once per exact mount, kind and step (keyed by every float's hex form: 0.0
    and -0.0 are different keys). Shapely geometries are immutable, so sharing is safe."""
    key = tuple(v.hex() if isinstance(v, float) else str(v) for v in (*astuple(m), *kind, dphi_deg))
    hit: Area | None = _memo.recall(key)
    if hit is not None:
        return hit
    if kind[0] == "any":
        fn = _any_height_fn(m, float(kind[1]), float(kind[2]))
    else:
        fn = _at_height_fn(m, float(kind[1]))
    area: Area = _memo.keep(key, _polar_region(m, fn, dphi_deg))
    return area


# --------------------------------------------------------------------------- system level


def vehicle_polygon(system: System) -> Polygon:
    """The vehicle footprint rectangle (vehicle frame, m)."""
    return Polygon(system.config.vehicle.footprint())


def near_field_window(system: System, radius: float = NEAR_FIELD_RADIUS_M) -> Polygon:
    """The near-field window: the footprint rectangle grown by ``radius`` m on every side."""
    if not (math.isfinite(radius) and radius > 0.0):
        raise ValueError(f"near-field radius must be > 0 m, got {radius!r}")
    xmin, ymin, xmax, ymax = vehicle_polygon(system).bounds
    return box(xmin - radius, ymin - radius, xmax + radius, ymax + radius)


def _window(system: System, extent: Sequence[float] | None, radius: float) -> Polygon:
    if extent is None:
        return near_field_window(system, radius)
    xmin, xmax, ymin, ymax = (float(v) for v in extent)
    if not (
        all(math.isfinite(v) for v in (xmin, xmax, ymin, ymax)) and xmin < xmax and ymin < ymax
    ):
        raise ValueError(
            f"extent must be finite (xmin, xmax, ymin, ymax) with xmin < xmax "
            f"and ymin < ymax, got {tuple(extent)!r}"
        )
    return box(xmin, ymin, xmax, ymax)


def any_height_footprints(
    system: System, height_range: tuple[float, float] = HEIGHT_RANGE_M, dphi_deg: float = DPHI_DEG
) -> dict[str, Area]:
    """Any-height footprint of every sensor, by sensor id (file order)."""
    return {s.id: sensor_footprint_any_height(s, height_range, dphi_deg) for s in system.sensors}


def at_height_footprints(
    system: System, z: float = MIN_OBJECT_HEIGHT_M, dphi_deg: float = DPHI_DEG
) -> dict[str, Area]:
    """Footprint of every sensor at height ``z`` (m), by sensor id (file order)."""
    return {s.id: sensor_footprint_at_height(s, z, dphi_deg) for s in system.sensors}


def _polygons(g: BaseGeometry) -> list[Polygon]:
    if isinstance(g, Polygon):
        return [] if g.is_empty else [g]
    return [p for p in getattr(g, "geoms", []) if isinstance(p, Polygon) and not p.is_empty]


def holes(
    covered: Sequence[BaseGeometry],
    body: Polygon,
    window: Polygon | None = None,
    union: BaseGeometry | None = None,
) -> list[Polygon]:
    """Bounded uncovered regions: the connected components of the complement of the union
    of ``covered`` and ``body`` that do not reach infinity (those lying inside ``window`` if
    given), largest first (ties by position). Regions that touch the outside only at a
    point count as enclosed (as for 4-connected grid cells). Overlay slivers below
    ``MIN_HOLE_M2`` are dropped. ``union``: that union if the caller has it."""
    if union is None:
        union = shapely.union_all([*covered, body], grid_size=SNAP_M)
    xmin, ymin, xmax, ymax = union.bounds
    frame = box(xmin - 1.0, ymin - 1.0, xmax + 1.0, ymax + 1.0)
    found: list[Polygon] = []
    for part in _polygons(shapely.difference(frame, union, grid_size=SNAP_M)):
        if part.intersects(frame.exterior) or part.area < MIN_HOLE_M2:
            continue
        if window is None or window.covers(part):
            found.append(part)
    found.sort(key=lambda p: (-round(p.area, 9), p.centroid.x, p.centroid.y))
    return found


def blind_spots(
    system: System,
    radius: float = NEAR_FIELD_RADIUS_M,
    height_range: tuple[float, float] = HEIGHT_RANGE_M,
    dphi_deg: float = DPHI_DEG,
    footprints: dict[str, Area] | None = None,
) -> list[Polygon]:
    """Blind spots (paper Fig. 5, blue): regions outside the vehicle footprint, enclosed by
    covered area, that no sensor sees at any height in ``height_range``; only those lying
    inside the near-field window (footprint grown by ``radius`` m). Polygons in m."""
    fps = _any_height(system, height_range, dphi_deg, footprints)
    return holes(list(fps.values()), vehicle_polygon(system), near_field_window(system, radius))


def uncovered_at_height(
    system: System,
    z: float = MIN_OBJECT_HEIGHT_M,
    extent: Sequence[float] | None = None,
    radius: float = NEAR_FIELD_RADIUS_M,
    dphi_deg: float = DPHI_DEG,
    footprints: dict[str, Area] | None = None,
) -> Area:
    """Region (m) of the near-field window outside the vehicle footprint that no sensor
    sees at height ``z`` (paper Fig. 5, green, at 0.1 m). The window is ``extent``
    ``(xmin, xmax, ymin, ymax)`` if given, else the footprint grown by ``radius``."""
    fps = footprints if footprints is not None else at_height_footprints(system, z, dphi_deg)
    return _not_covered(_window(system, extent, radius), _covered(system, fps))


def _covered(system: System, footprints: dict[str, Area]) -> BaseGeometry:
    """The union of the vehicle footprint and every footprint (m)."""
    return shapely.union_all([*footprints.values(), vehicle_polygon(system)], grid_size=SNAP_M)


def _not_covered(window: Polygon, covered: BaseGeometry) -> Area:
    """The part of ``window`` (m) outside ``covered`` (``_covered``)."""
    return _as_area(shapely.difference(window, covered, grid_size=SNAP_M))


def _any_height(
    system: System,
    height_range: tuple[float, float],
    dphi_deg: float,
    footprints: dict[str, Area] | None,
) -> dict[str, Area]:
    """``footprints``, or the any-height footprints of ``system`` when not given."""
    if footprints is not None:
        return footprints
    return any_height_footprints(system, height_range, dphi_deg)


def unseen_at_any_height(
    system: System,
    radius: float = NEAR_FIELD_RADIUS_M,
    height_range: tuple[float, float] = HEIGHT_RANGE_M,
    dphi_deg: float = DPHI_DEG,
    footprints: dict[str, Area] | None = None,
) -> Area:
    """Region (m) of the near-field window (footprint grown by ``radius`` m) outside the
    vehicle footprint that no sensor sees at any height in ``height_range``: the enclosed
    blind spots (``blind_spots``, the paper's Fig. 5 measure) together with the unseen
    region open to the outside, which the paper's measure leaves out (a vehicle without
    rear sensors has no blind spot behind it by that measure, only this)."""
    fps = _any_height(system, height_range, dphi_deg, footprints)
    return _not_covered(near_field_window(system, radius), _covered(system, fps))


# --------------------------------------------------------------------------- grid method


@dataclass(frozen=True)
class GridNearField:
    """A grid classification of the near-field window.

    Cells are ``resolution`` wide from (xmin, ymin); the last row/column is clipped to the
    window, ``cell_area`` holds each cell's area (m2) inside it. ``mask[iy, ix]`` marks the
    cells counted (blind or uncovered); ``area`` is their total area, m2.
    """

    extent: tuple[float, float, float, float]
    resolution: float
    mask: NDArray[np.bool_]
    cell_area: F64
    area: float


def _cells(win: Polygon, res: float) -> tuple[F64, F64, F64, tuple[float, float, float, float]]:
    if not (math.isfinite(res) and res > 0.0):
        raise ValueError(f"resolution must be > 0 m, got {res!r}")
    xmin, ymin, xmax, ymax = win.bounds
    nx, ny = math.ceil((xmax - xmin) / res - 1e-9), math.ceil((ymax - ymin) / res - 1e-9)
    if nx * ny > 50_000_000:
        raise ValueError(f"grid of {nx * ny} cells is too large; coarsen the resolution")
    xe = np.minimum(xmin + np.arange(nx + 1) * res, xmax)
    ye = np.minimum(ymin + np.arange(ny + 1) * res, ymax)
    xc, yc = 0.5 * (xe[:-1] + xe[1:]), 0.5 * (ye[:-1] + ye[1:])
    gx, gy = np.meshgrid(xc, yc)
    area = np.outer(np.diff(ye), np.diff(xe))
    return gx, gy, area, (xmin, xmax, ymin, ymax)


def _in_body(system: System, gx: F64, gy: F64) -> NDArray[np.bool_]:
    xmin, ymin, xmax, ymax = vehicle_polygon(system).bounds
    return (gx >= xmin) & (gx <= xmax) & (gy >= ymin) & (gy <= ymax)


def _seen(m: Mount, px: F64, py: F64, z: float) -> NDArray[np.bool_]:
    xs, ys, zs = rotate_offsets(m, px - m.x, py - m.y, z - m.z)
    return fov_mask(m, xs, ys, zs) & in_range(m, np.sqrt(xs * xs + ys * ys + zs * zs))


def _seen_any_height(
    system: System, gx: F64, gy: F64, heights: F64, skip: NDArray[np.bool_]
) -> NDArray[np.bool_]:
    seen = np.zeros(gx.shape, dtype=bool)
    fx, fy, flat = gx.ravel(), gy.ravel(), seen.ravel()
    done = skip.ravel()
    for s in system.sensors:
        m = s.mount
        idx = np.flatnonzero(~flat & ~done)
        idx = idx[np.hypot(fx[idx] - m.x, fy[idx] - m.y) <= m.max_range]
        # the mount height first: the widest slice of most sensors
        for z in sorted(heights.tolist(), key=lambda h: (h != m.z, h)):
            if idx.size == 0:
                break
            hit = _seen(m, fx[idx], fy[idx], z)
            flat[idx[hit]] = True
            idx = idx[~hit]
    return seen


def grid_heights(
    system: System, resolution: float, height_range: tuple[float, float] = HEIGHT_RANGE_M
) -> F64:
    """Heights (m) sampled by the grid method: spacing <= ``resolution``, both ends of the
    height range and every mount height inside it."""
    lo, hi = height_range
    n = max(2, math.ceil((hi - lo) / resolution - 1e-9) + 1)
    zs = np.linspace(lo, hi, n).tolist()
    zs += [s.mount.z for s in system.sensors if lo <= s.mount.z <= hi]
    return np.unique(np.array(zs, dtype=np.float64))


def grid_blind_spots(
    system: System,
    resolution: float,
    radius: float = NEAR_FIELD_RADIUS_M,
    height_range: tuple[float, float] = HEIGHT_RANGE_M,
) -> GridNearField:
    """Blind spots on a grid over the near-field window: cells whose centre is outside the
    vehicle footprint and seen by no sensor at any sampled height (``grid_heights``),
    grouped into 4-connected components; components touching the window border are not
    enclosed and do not count."""
    from scipy import ndimage

    for s in system.sensors:
        _check_heights(s.mount, height_range)
    gx, gy, area, ext = _cells(near_field_window(system, radius), resolution)
    body = _in_body(system, gx, gy)
    seen = _seen_any_height(system, gx, gy, grid_heights(system, resolution, height_range), body)
    free = ~seen & ~body
    labels, _ = ndimage.label(free)
    border = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    mask = free & ~np.isin(labels, border)
    return GridNearField(ext, resolution, mask, area, float(np.sum(area[mask])))


def grid_uncovered_at_height(
    system: System,
    z: float = MIN_OBJECT_HEIGHT_M,
    resolution: float = 0.05,
    extent: Sequence[float] | None = None,
    radius: float = NEAR_FIELD_RADIUS_M,
) -> GridNearField:
    """Cells of the near-field window, centre outside the vehicle footprint, that no sensor
    sees at height ``z`` (m)."""
    gx, gy, area, ext = _cells(_window(system, extent, radius), resolution)
    body = _in_body(system, gx, gy)
    seen = np.zeros(gx.shape, dtype=bool)
    for s in system.sensors:
        todo = ~seen & ~body
        seen[todo] = _seen(s.mount, gx[todo], gy[todo], z)
    mask = ~seen & ~body
    return GridNearField(ext, resolution, mask, area, float(np.sum(area[mask])))


# --------------------------------------------------------------------------- outputs


def _r(v: float) -> float:
    return round(float(v), 6) + 0.0


def _path_patch(geom: BaseGeometry, **kw: Any) -> Any:
    from sensorgap.runtime import pristine_matplotlib

    pristine_matplotlib()
    from matplotlib.patches import PathPatch
    from matplotlib.path import Path as MplPath

    verts: list[Any] = []
    codes: list[int] = []
    for poly in _polygons(geom):
        for ring in (poly.exterior, *poly.interiors):
            xy = np.asarray(ring.coords)
            verts.extend(xy.tolist())
            codes.extend(
                [int(MplPath.MOVETO)]
                + [int(MplPath.LINETO)] * (len(xy) - 2)
                + [int(MplPath.CLOSEPOLY)]
            )
    if not verts:
        return None
    return PathPatch(MplPath(verts, codes), **kw)


def nearfield_figure(
    system: System,
    window: Polygon,
    footprints: dict[str, Area],
    spots: list[Polygon],
    uncovered: BaseGeometry,
    z: float,
    unseen: BaseGeometry | None = None,
) -> Any:
    """Fig. 5 style: vehicle, sensor footprints (outlines), blind spots blue, area not
    covered at height ``z`` green, and (hatched) the part of ``unseen`` (no sensor at any
    height, ``unseen_at_any_height``) open to the outside; axes in metres, equal aspect;
    the legend below the plot."""
    from sensorgap.runtime import pristine_matplotlib

    pristine_matplotlib()
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    from sensorgap.coverage.plot import draw_vehicle, plain_text, sensor_colour

    xmin, ymin, xmax, ymax = window.bounds
    aspect = (ymax - ymin) / (xmax - xmin)
    fig, ax = plt.subplots(figsize=(9.0, max(3.5, 9.0 * aspect + 1.3)), layout="constrained")
    # the polygons go in with add_artist, not add_patch: add_patch also grows the data
    # limits vertex by vertex (most of the figure's time for footprints of thousands of
    # vertices), which nothing here reads: the limits are set to the window below
    if (
        p := _path_patch(uncovered, facecolor="tab:green", edgecolor="none", alpha=0.55, zorder=1)
    ) is not None:
        ax.add_artist(p)
    for spot in spots:
        if (
            p := _path_patch(spot, facecolor="tab:blue", edgecolor="navy", linewidth=0.6, zorder=3)
        ) is not None:
            ax.add_artist(p)
    open_area = 0.0
    if unseen is not None:
        outside = shapely.difference(unseen, shapely.union_all(spots), grid_size=SNAP_M)
        open_area = float(outside.area)
        if (
            p := _path_patch(
                outside,
                facecolor="none",
                edgecolor="dimgray",
                hatch="////",
                linewidth=0.0,
                zorder=3,
            )
        ) is not None:
            ax.add_artist(p)
    types_used = []
    for s in system.sensors:
        colour = sensor_colour(s.type_name)
        clipped = shapely.intersection(footprints[s.id], window.buffer(1.0, join_style=2))
        if (
            p := _path_patch(clipped, facecolor=colour, edgecolor="none", alpha=0.07, zorder=0)
        ) is not None:
            ax.add_artist(p)
        if (
            p := _path_patch(
                clipped, facecolor="none", edgecolor=colour, linewidth=0.5, alpha=0.7, zorder=2
            )
        ) is not None:
            ax.add_artist(p)
        ax.plot([s.mount.x], [s.mount.y], marker="o", markersize=2.5, color=colour, zorder=6)
        if s.type_name not in types_used:
            types_used.append(s.type_name)
    draw_vehicle(ax, system, fov=False)
    ax.set_xlim(xmin, xmax)
    ax.set_ylim(ymin, ymax)
    ax.set_aspect("equal")
    ax.set_xlabel("x (vehicle frame) [m]")
    ax.set_ylabel("y (vehicle frame) [m]")
    area = sum(sp.area for sp in spots)
    seen_nowhere = (
        f"\nno sensor at any height, open to the outside: {open_area:.2f} m$^2$ (hatched)"
        if open_area >= 0.005
        else ""
    )
    ax.set_title(
        f"{plain_text(system.name)}: blind spots {area:.2f} m$^2$ (blue), not covered at "
        f"{z:g} m (green){seen_nowhere}",
        fontsize=10,
    )
    handles: list[Any] = [
        Patch(facecolor="tab:blue", edgecolor="navy", label="blind spot (no sensor, any height)"),
        Patch(facecolor="tab:green", alpha=0.55, label=f"not covered at {z:g} m"),
    ]
    if open_area >= 0.005:
        handles.append(
            Patch(
                facecolor="none",
                edgecolor="dimgray",
                hatch="////",
                label="no sensor at any height, open to the outside",
            )
        )
    handles += [
        Line2D(
            [],
            [],
            color=sensor_colour(t),
            linewidth=1.0,
            label=f"{t} footprint (any height)",
        )
        for t in types_used
    ]
    # below the plot, never over the blind spots or the sensors
    fig.legend(handles=handles, loc="outside lower center", ncol=3, fontsize=7, frameon=False)
    return fig


class _NearField(NamedTuple):
    """What ``write_nearfield`` writes, computed (immutable shapely areas; ``summary`` is
    copied before it is handed out)."""

    window: Polygon
    fp_any: dict[str, Area]
    spots: list[Polygon]
    uncovered: Area
    unseen: Area
    summary: dict[str, Any]


#: Near fields kept for a later call for the same vehicle and settings (a job's and a
#: comparison's near field of one vehicle): at most this many, least recently used dropped.
NEARFIELD_MEMO = 8
_nearfield_memo = _Memo(lambda: NEARFIELD_MEMO)


def clear_memo() -> None:
    """Forget every memoised footprint, near field and figure (``coverage.figurememo``;
    the next call computes them again: the determinism tests compare two computations,
    not a computation and its copy)."""
    _memo.clear()
    _nearfield_memo.clear()
    from sensorgap.coverage.figurememo import clear_memo as clear_figures

    clear_figures()


def _nearfield_key(system: System, *settings: float) -> tuple[str, ...]:
    """What a near field depends on: the vehicle's name, body, each sensor's id and mount,
    and the ``settings`` (resolution, radius, height range, z, angular step), every float
    by its hex form."""
    return (
        system.name,
        system.config.vehicle.model_dump_json(),
        *(s.id + ":" + ",".join(float(v).hex() for v in astuple(s.mount)) for s in system.sensors),
        *(float(v).hex() for v in settings),
    )


def _nearfield_result(
    system: System,
    resolution: float,
    radius: float,
    height_range: tuple[float, float],
    z: float,
    dphi_deg: float,
) -> _NearField:
    """The near field of ``system`` (exact and grid; see ``write_nearfield``), computed
    once per vehicle and settings: its name, body, each sensor's id and mount, and the
    settings, every float by its hex form (what the near field depends on)."""
    key = _nearfield_key(system, resolution, radius, *height_range, z, dphi_deg)
    hit: _NearField | None = _nearfield_memo.recall(key)
    if hit is not None:
        return hit
    win = near_field_window(system, radius)
    fp_any = any_height_footprints(system, height_range, dphi_deg)
    fp_z = at_height_footprints(system, z, dphi_deg)
    union = _covered(system, fp_any)  # once, for the holes and the unseen area
    every_hole = holes(list(fp_any.values()), vehicle_polygon(system), union=union)
    spots = [h for h in every_hole if win.covers(h)]
    unc = uncovered_at_height(system, z, None, radius, dphi_deg, footprints=fp_z)
    unseen = _not_covered(win, union)  # as unseen_at_any_height
    g_bs = grid_blind_spots(system, resolution, radius, height_range)
    g_un = grid_uncovered_at_height(system, z, resolution, None, radius)
    exact_bs = sum(p.area for p in spots)
    xmin, ymin, xmax, ymax = win.bounds
    summary: dict[str, Any] = {
        "system": system.name,
        "window": {
            "definition": f"vehicle footprint rectangle grown by {radius:g} m",
            "radius_m": _r(radius),
            "xmin": _r(xmin),
            "xmax": _r(xmax),
            "ymin": _r(ymin),
            "ymax": _r(ymax),
            "area_m2": _r(win.area),
        },
        "height_range_m": [_r(height_range[0]), _r(height_range[1])],
        "blind_spot_m2": {
            "exact": _r(exact_bs),
            "holes": [
                {
                    "area_m2": _r(p.area),
                    "centroid_m": [_r(p.centroid.x), _r(p.centroid.y)],
                    "bounds_m": [_r(v) for v in p.bounds],
                }
                for p in spots
            ],
            "grid": _r(g_bs.area),
            "resolution_m": _r(resolution),
            "difference": _r(g_bs.area - exact_bs),
            "holes_outside_window": len(every_hole) - len(spots),
        },
        "unseen_any_height_m2": {
            "definition": "the window outside the body that no sensor sees at any height "
            "in the height range: the enclosed blind spots and the region open to the outside",
            "exact": _r(unseen.area),
            "enclosed": _r(exact_bs),
            "open_to_outside": _r(max(unseen.area - exact_bs, 0.0)),
        },
        "uncovered_0p1m_m2": {
            "height_m": _r(z),
            "exact": _r(unc.area),
            "grid": _r(g_un.area),
            "resolution_m": _r(resolution),
            "difference": _r(g_un.area - unc.area),
        },
        "method": {
            "exact": f"polar boundary sampled every {dphi_deg:g} deg, structural changes "
            "located to 1e-12 rad, shapely overlay snapped to 1e-9 m",
            "grid": "cell centres, fov_mask/in_range at heights every <= resolution plus "
            "the range ends and mount heights; 4-connected holes",
            "grid_heights": len(grid_heights(system, resolution, height_range)),
            "self_occlusion": False,
        },
    }
    result: _NearField = _nearfield_memo.keep(
        key, _NearField(win, fp_any, spots, unc, unseen, summary)
    )
    return result


def write_nearfield(
    system: System,
    out_dir: Path,
    resolution: float = 0.05,
    radius: float = NEAR_FIELD_RADIUS_M,
    height_range: tuple[float, float] = HEIGHT_RANGE_M,
    z: float = MIN_OBJECT_HEIGHT_M,
    dphi_deg: float = DPHI_DEG,
) -> dict[str, Any]:
    """Write ``nearfield.json`` and ``nearfield.png`` into ``out_dir``; return the summary.

    Summary keys: ``system``, ``window``, ``height_range_m``, ``blind_spot_m2`` (exact,
    per-hole, grid, resolution, difference), ``unseen_any_height_m2`` (exact: enclosed and
    open to the outside), ``uncovered_0p1m_m2`` (same as the blind spots, at ``z``),
    ``method``. Same inputs -> byte-identical files.
    """
    from sensorgap.coverage.figurememo import save_drawn

    out_dir = Path(out_dir)
    lo, hi = height_range
    for sensor in system.sensors:
        if not (lo <= sensor.mount.z <= hi):
            raise InputError(
                system.source,
                f"sensors[id={sensor.id}].position_m",
                f"mount height {sensor.mount.z:g} m is outside the near-field "
                f"object heights {lo:g}..{hi:g} m",
            )
    r = _nearfield_result(system, resolution, radius, height_range, z, dphi_deg)
    summary = copy.deepcopy(r.summary)
    write_json(out_dir / "nearfield.json", summary)
    # the figure reads the near field (its key) and each sensor's type (its colour)
    save_drawn(
        (
            "nearfield_figure",
            _nearfield_key(system, resolution, radius, *height_range, z, dphi_deg),
            tuple(s.type_name for s in system.sensors),
        ),
        lambda: nearfield_figure(system, r.window, r.fp_any, r.spots, r.uncovered, z, r.unseen),
        out_dir / "nearfield.png",
    )
    return summary
