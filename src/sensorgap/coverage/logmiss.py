"""Fused detection at many points in the log domain, with a per-point sun, exact or by map
lookup: the evaluation core of the scenario search.

Eq. 11 in the log domain: the fused miss probability at a point is
``ln P_miss = sum_i ln(1 - Pd_i)`` with every ``Pd_i`` capped at ``1 - 2^-53``
(``LOG_MISS_MIN`` = -36.7 per sensor), so a certain detection stays finite and sums of many
steps never underflow.

Glare: a scene is prepared without a sun direction; cameras that the direct sun can blind
(``PreparedSensor.snr_db_glare``) are evaluated with their glare weight per point, computed
from that point's vehicle-frame sun direction (``SensorModel.glare_weights``). A turning ego
therefore sees the sun move through its cameras step by step, without quantising headings.

Lookup (``LogMissMaps``): per-sensor ``ln(1 - Pd)`` maps without sun on a regular grid and
their sum; bilinear interpolation is linear, so the interpolated sum equals the sum of the
interpolated sensors. For glare-prone cameras the maps also hold the received signal (dB,
``PreparedSensor.signal_db``) in the cells in view: where the sun glares a camera at a
point, its layer is replaced by the ROC of ``snr_from_signal(interpolated signal, w)``; at
the edge of its field of view (a corner cell out of view) and outside the map the point is
evaluated exactly. The only approximation is the interpolation between cell centres (error
measured in ``benchmarks/bench_search.py`` and ``sensorgap tradeoff``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.fastglare import glared_pass
from sensorgap.coverage.fastkernel import mount_constants, roc_constants
from sensorgap.coverage.fastlookup import (
    bilerp,
    bilinear_finite_at,
    body_layer_pass,
    cone_cos_bound,
    lookup_pass,
    map_cell,
    near_view_mask,
    sun_directions_at,
)
from sensorgap.coverage.grid import GridSpec, evaluate_grid
from sensorgap.coverage.kernel import candidates, evaluate_offsets
from sensorgap.coverage.scene import Scene
from sensorgap.jit import njit
from sensorgap.models.base import glare_factors
from sensorgap.models.geometry import fov_mask, in_range, rotate_offsets, sensor_range, spherical
from sensorgap.models.numerics import clip_snr_db
from sensorgap.models.roc import detection_probability
from sensorgap.models.system import Sensor

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
IntArr = NDArray[np.intp]

#: Largest per-sensor Pd used in the log domain (1 - 2^-53), and its ln(1 - Pd).
ALMOST_ONE = float(np.nextafter(1.0, 0.0))
LOG_MISS_MIN = math.log1p(-ALMOST_ONE)


def log_miss_of(pd: F64) -> F64:
    """ln(1 - Pd) with Pd capped at ``ALMOST_ONE`` (finite, <= 0)."""
    return np.asarray(np.log1p(-np.minimum(pd, ALMOST_ONE)), dtype=np.float64)


def glare_weights(sensor: Sensor, sun_dirs: F64 | None, index: IntArr) -> F64 | None:
    """Glare weight (the sun in or near the view) per selected point (``None``: no sun,
    or the sensor is immune)."""
    if sun_dirs is None or index.size == 0:
        return None
    w = sensor.model.glare_weights(sensor.mount, sun_dirs[index])
    return w if bool(np.any(w > 0.0)) else None


def _glare_at(
    sensor: Sensor, x: F64, y: F64, z: F64 | float, sun_dirs: F64, weights: F64
) -> tuple[F64, F64]:
    """Glare factors (``models.base.glare_factors``) of a camera at vehicle-frame points
    (m) with their sun directions and glare weights, and the points' ranges (m)."""
    m = sensor.mount
    dx, dy = x - m.x, y - m.y
    dz = np.broadcast_to(np.asarray(z, dtype=np.float64) - m.z, dx.shape)
    fac = glare_factors(sensor.model, m, dx, dy, dz, sun_dirs, weights)
    return fac, np.sqrt(dx * dx + dy * dy + dz * dz)


#: The outline of a body reduced to its centre (target frame, m).
_CENTRE = np.zeros((1, 2))


class GlaredBodies(NamedTuple):
    """M target bodies under a glared camera: centres ``x``, ``y`` (m, vehicle frame),
    headings ``psi`` (rad), heights ``z`` (m), sun directions ((M, 3) vehicle-frame unit
    vectors) and the camera's glare weights."""

    x: F64
    y: F64
    psi: F64
    z: F64
    sun_dirs: F64
    weights: F64


def _glared_values(
    maps: LogMissMaps, scene: Scene, row: int, bodies: GlaredBodies, outline: F64
) -> tuple[F64, NDArray[np.int8]]:
    """A glared camera's ln(1 - Pd) from its signal map at the K ``outline`` points ((K, 2),
    target frame, m) of M ``bodies``: the ROC of ``snr_from_signal`` of the interpolated
    signal with the point's glare factor, where the four cells around the point are in
    view (state 1); 0 with state 0 (out of view) or 2 (the edge of the view, or no signal
    map): the caller evaluates those exactly. (M, K) values and states. Compiled
    (``fastglare.glared_pass``) for the built-in camera with a closed-form ROC, which
    evaluates the edge points exactly itself (state 3: its ``signal_constants``);
    ``_glared_values_numpy`` otherwise (and, with the exact evaluation of its state-2
    points, as the reference)."""
    n, k = len(bodies.x), len(outline)
    if row not in maps.signal or scene.prepared(scene.sensors[row]).snr_from_signal is None:
        return np.zeros((n, k)), np.full((n, k), 2, dtype=np.int8)
    cc = _compiled_camera(scene, row)
    if cc is None:
        return _glared_values_numpy(maps, scene, row, bodies, outline)
    out = np.empty((n, k))
    state = np.empty((n, k), dtype=np.int8)
    glared_pass(
        maps.signal[row],
        *maps.grid.lookup_origin(),
        np.ascontiguousarray(bodies.x, dtype=np.float64),
        np.ascontiguousarray(bodies.y, dtype=np.float64),
        np.ascontiguousarray(bodies.psi, dtype=np.float64),
        np.ascontiguousarray(outline, dtype=np.float64),
        np.ascontiguousarray(bodies.z, dtype=np.float64),
        cc.mount,
        np.ascontiguousarray(bodies.sun_dirs, dtype=np.float64),
        np.ascontiguousarray(bodies.weights, dtype=np.float64),
        cc.veil,
        cc.roc_code,
        cc.roc,
        cc.view,
        cc.signal,
        out,
        state,
    )
    return out, state


class _CompiledCamera(NamedTuple):
    """What ``fastglare.glared_pass`` needs of a glare-prone camera, as arrays: its
    position (m), ``veil_constants``, ROC kind and constants, ``mount_constants`` and
    ``signal_constants`` (empty: edge points left to numpy)."""

    mount: F64
    veil: F64
    roc_code: int
    roc: F64
    view: F64
    signal: F64


def _compiled_camera(scene: Scene, row: int) -> _CompiledCamera | None:
    """``_CompiledCamera`` of sensor ``row`` (``None``: no compiled form: another sensor
    type or ROC kind); cached on the scene (they were rebuilt at every call)."""
    cache: dict[int, _CompiledCamera | None] = scene.__dict__.setdefault("_compiled_cameras", {})
    if row not in cache:
        s = scene.sensors[row]
        prepared = scene.prepared(s)
        roc = roc_constants(s.roc, scene.roc_shift_db)
        cache[row] = (
            None
            if prepared.veil_constants is None or roc is None
            else _CompiledCamera(
                np.array([s.mount.x, s.mount.y, s.mount.z]),
                np.array(prepared.veil_constants, dtype=np.float64),
                roc[0],
                roc[1],
                mount_constants(s.mount),
                np.array(prepared.signal_constants or (), dtype=np.float64),
            )
        )
    return cache[row]


def _glared_values_numpy(
    maps: LogMissMaps, scene: Scene, row: int, bodies: GlaredBodies, outline: F64
) -> tuple[F64, NDArray[np.int8]]:
    """``_glared_values`` through the sensor's own ``snr_from_signal`` and ROC (numpy)."""
    s = scene.sensors[row]
    prepared = scene.prepared(s)
    assert prepared.snr_from_signal is not None
    n, k = len(bodies.x), len(outline)
    c, sn = np.cos(bodies.psi)[:, None], np.sin(bodies.psi)[:, None]
    ox, oy = outline[:, 0][None, :], outline[:, 1][None, :]
    px = (bodies.x[:, None] + c * ox - sn * oy).ravel()
    py = (bodies.y[:, None] + sn * ox + c * oy).ravel()
    sig, state = maps.interpolate_signal(row, px, py)
    new = np.zeros(px.size)
    ok = np.flatnonzero(state == 1)
    if ok.size:
        b = ok // k
        fac, rng = _glare_at(s, px[ok], py[ok], bodies.z[b], bodies.sun_dirs[b], bodies.weights[b])
        snr = clip_snr_db(prepared.snr_from_signal(sig[ok], fac, rng))
        new[ok] = log_miss_of(detection_probability(snr, s.roc, scene.roc_shift_db))
    return new.reshape(n, k), state.reshape(n, k)


def _bodies(x: F64, y: F64, psi: F64, z: F64 | float, sun_dirs: F64, weights: F64) -> GlaredBodies:
    """``GlaredBodies`` with the height broadcast to every body."""
    return GlaredBodies(
        x, y, psi, np.broadcast_to(np.asarray(z, dtype=np.float64), (len(x),)), sun_dirs, weights
    )


def _centres(x: F64, y: F64, z: F64 | float, sun_dirs: F64, weights: F64) -> GlaredBodies:
    """``GlaredBodies`` reduced to points (heading 0, outline ``_CENTRE``) at vehicle-frame
    ``x``, ``y``, height ``z`` (m)."""
    return _bodies(x, y, np.zeros(len(x)), z, sun_dirs, weights)


def _glared_from_maps(
    maps: LogMissMaps, scene: Scene, row: int, centres: GlaredBodies
) -> tuple[F64, NDArray[np.int8]]:
    """A glared camera's ln(1 - Pd) at points (``_centres``) from its signal map (the one
    glare correction of every lookup): ``_glared_values`` at the points, and their states."""
    vals, state = _glared_values(maps, scene, row, centres, _CENTRE)
    return vals[:, 0], state[:, 0]


def sensor_snr(
    scene: Scene, sensor: Sensor, x: F64, y: F64, z: F64, sun_dirs: F64 | None = None
) -> tuple[IntArr, F64]:
    """SNR (dB) of one sensor at flat vehicle-frame points (m) with a per-point sun.

    ``sun_dirs``: (N, 3) unit vectors to the sun in the vehicle frame (rows of NaN: no
    direct sun) or ``None``. ``scene`` must be prepared without a sun direction. Returns
    ``(index, snr_db)`` for the points in view; every other point has Pd = 0.
    """
    m = sensor.mount
    dx, dy, dz = x - m.x, y - m.y, z - m.z
    idx = candidates(sensor, dx * dx + dy * dy + dz * dz)
    if idx.size == 0:
        return idx, np.empty(0)
    ok, snr, _ = evaluate_offsets(scene, sensor, dx[idx], dy[idx], dz[idx])
    idx = idx[ok]
    prepared = scene.prepared(sensor)
    if prepared.snr_db_glare is None:
        return idx, snr
    w = glare_weights(sensor, sun_dirs, idx)
    if w is None:
        return idx, snr
    g = np.flatnonzero(w > 0.0)
    gx, gy, gz = dx[idx[g]], dy[idx[g]], dz[idx[g]]
    assert sun_dirs is not None
    fac = glare_factors(sensor.model, m, gx, gy, gz, sun_dirs[idx[g]], w[g])
    xs, ys, zs = rotate_offsets(m, gx, gy, gz)
    r = sensor_range(xs, ys, zs)
    _, az, el = spherical(xs, ys, zs)
    snr = snr.copy()
    snr[g] = clip_snr_db(prepared.snr_db_glare(r, az, el, fac))
    return idx, snr


def sensor_pd(
    scene: Scene, sensor: Sensor, x: F64, y: F64, z: F64, sun_dirs: F64 | None = None
) -> tuple[IntArr, F64]:
    """Pd of one sensor at flat vehicle-frame points (m) with a per-point sun (see
    ``sensor_snr``). Returns ``(index, pd)`` for the points in view."""
    idx, snr = sensor_snr(scene, sensor, x, y, z, sun_dirs)
    return idx, detection_probability(snr, sensor.roc, scene.roc_shift_db)


def sensor_log_miss(
    scene: Scene, sensor: Sensor, x: F64, y: F64, z: F64, sun_dirs: F64 | None = None
) -> F64:
    """ln(1 - Pd) of one sensor at every flat vehicle-frame point (m; 0 out of its view),
    with a per-point sun (see ``sensor_snr``)."""
    idx, pd = sensor_pd(scene, sensor, x, y, z, sun_dirs)
    vals = np.zeros(np.shape(x))
    vals[idx] = log_miss_of(pd)
    return vals


def _glare_change(
    maps: LogMissMaps,
    scene: Scene,
    row: int,
    centres: GlaredBodies,
    exact_edge: Callable[[NDArray[np.int64]], F64],
) -> tuple[F64, int]:
    """The change of a glared camera's ln(1 - Pd) at points (``_centres``) when its layer
    of the maps is replaced by its glared value from the signal map, exact where a point
    lies at the edge of its view (``exact_edge(indices into the points)``). Returns the
    changes and how many points were evaluated exactly."""
    layer, _ = maps.interpolate(row, centres.x, centres.y)
    new, state = _glared_from_maps(maps, scene, row, centres)
    edge = np.flatnonzero(state == 2)
    if edge.size:  # at the edge of the field of view: exact
        new[edge] = exact_edge(edge)
    # (state 3: at the edge too, evaluated exactly in the compiled pass)
    return new - layer, int(edge.size) + int(np.count_nonzero(state == 3))


def exact_log_miss(
    scene: Scene,
    x: F64,
    y: F64,
    z: F64,
    sun_dirs: F64 | None = None,
    sensors: Sequence[Sensor] | None = None,
) -> F64:
    """Fused ln P_miss at flat points (m), exact, per-point sun (see ``sensor_pd``)."""
    out = np.zeros(len(x))
    for s in scene.sensors if sensors is None else sensors:
        idx, pd = sensor_pd(scene, s, x, y, z, sun_dirs)
        if idx.size:
            out[idx] += log_miss_of(pd)
    return out


def per_sensor_pd(scene: Scene, x: F64, y: F64, z: F64, sun_dirs: F64 | None = None) -> F64:
    """(S, N) Pd of every sensor of the scene at flat points (m), exact, per-point sun."""
    out = np.zeros((len(scene.sensors), len(x)))
    for row, s in enumerate(scene.sensors):
        idx, pd = sensor_pd(scene, s, x, y, z, sun_dirs)
        out[row, idx] = pd
    return out


@njit(nogil=True)
def _bilinear(
    img: F32,
    x0: float,
    y0: float,
    inv_res: float,
    xs: F64,
    ys: F64,
    finite: bool,
    out: F64,
    flags: NDArray[np.int8],
) -> None:  # pragma: no cover - compiled
    """Bilinear interpolation of ``img`` at each point (m; ``x0``, ``y0``: first cell
    centre, m; ``inv_res``: cells per m). ``finite`` (a map NaN out of view):
    ``fastlookup.bilinear_finite_at``, ``flags`` 1 = all four corner cells in view
    (interpolated), 0 = none (out of view), 2 = some (the edge of the field of view) or
    outside the map; else ``flags`` 1 inside the map, 0 outside (value 0)."""
    ny, nx = img.shape
    for k in range(xs.size):
        if finite:
            out[k], flags[k] = bilinear_finite_at(img, x0, y0, inv_res, xs[k], ys[k])
            continue
        on_map, i, j, ax, ay = map_cell(x0, y0, inv_res, nx, ny, xs[k], ys[k])
        if not on_map:
            flags[k] = 0
            out[k] = 0.0
            continue
        flags[k] = 1
        out[k] = bilerp(ax, ay, img[j, i], img[j, i + 1], img[j + 1, i], img[j + 1, i + 1])


def interpolate_map(
    grid: GridSpec, img: NDArray[np.floating], x: F64, y: F64, finite: bool = False
) -> tuple[F64, NDArray[np.int8]]:
    """Bilinear value of a (ny, nx) map on ``grid`` at vehicle-frame points (m) and a flag
    per point (``_bilinear``: inside the map 1, outside 0 with value 0; ``finite``, a map
    NaN out of view: 1 interpolated, 0 out of view, 2 edge or outside)."""
    out = np.empty(len(x))
    flags = np.empty(len(x), dtype=np.int8)
    _bilinear(
        img,
        *grid.lookup_origin(),
        np.ascontiguousarray(x, dtype=np.float64),
        np.ascontiguousarray(y, dtype=np.float64),
        finite,
        out,
        flags,
    )
    return out, flags


def signal_layer(scene: Scene, sensor: Sensor, grid: GridSpec) -> F32 | None:
    """Received signal (dB) of a glare-prone sensor at the grid's cells in view (NaN
    elsewhere), or ``None`` if the sensor has no ``signal_db``."""
    prepared = scene.prepared(sensor)
    if prepared.signal_db is None:
        return None
    xx, yy = np.meshgrid(grid.xs(), grid.ys())
    m = sensor.mount
    dx, dy = xx.ravel() - m.x, yy.ravel() - m.y
    dz = np.full(dx.size, grid.height - m.z)
    out = np.full(dx.size, np.nan, dtype=np.float32)
    xs, ys, zs = rotate_offsets(m, dx, dy, dz)
    r = sensor_range(xs, ys, zs)
    ok = fov_mask(m, xs, ys, zs) & in_range(m, r) & (r > 0.0)
    if ok.any():
        _, az, el = spherical(xs[ok], ys[ok], zs[ok])
        out[ok] = prepared.signal_db(r[ok], az, el)
    return out.reshape(grid.ny, grid.nx)


@dataclass(frozen=True)
class BodyLayer:
    """One sensor's part of the body maps (``LogMissMaps.body_layer``): ``values`` (H,
    cy, cx) float32 ln(1 - Pd) per heading bin on the crop of the map starting at row
    ``j0``, column ``i0`` (0 outside the crop)."""

    j0: int
    i0: int
    values: F32


@dataclass
class LogMissMaps:
    """Per-sensor ln(1 - Pd) maps (no sun) of one scene and their sum.

    Attributes:
        grid: the grid (cell centres, m; height = the target's reference height).
        sensor_ids: layer order (the system's sensor order).
        layers: (S, ny, nx) float32 ln(1 - Pd_i), >= ``LOG_MISS_MIN``.
        total: (ny, nx) float32, sum over the layers (summed in float64).
        signal: glare-prone sensor index -> (ny, nx) float32 received signal, dB (NaN out
            of view).
    """

    grid: GridSpec
    sensor_ids: list[str]
    layers: F32
    total: F32
    signal: dict[int, F32]

    @classmethod
    def build(cls, scene: Scene, grid: GridSpec, workers: int = 1) -> LogMissMaps:
        """Evaluate the scene (which must have no sun direction) on ``grid``."""
        if scene.conditions.sun_direction is not None:
            raise ValueError("lookup maps are built without a sun direction")
        cov = evaluate_grid(scene, grid, per_sensor=True, workers=workers)
        ids = [s.id for s in scene.sensors]
        layers = np.zeros((len(ids), grid.ny, grid.nx), dtype=np.float32)
        total = np.zeros((grid.ny, grid.nx), dtype=np.float64)
        for i, sid in enumerate(ids):
            if sid in cov.pd:
                lm = log_miss_of(np.asarray(cov.pd[sid], dtype=np.float64))
                layers[i] = lm
                total += lm
        signal = {}
        for i, s in enumerate(scene.sensors):
            sig = signal_layer(scene, s, grid)
            if sig is not None:
                signal[i] = sig
        return cls(grid, ids, layers, total.astype(np.float32), signal)

    def signal_stack(self, sensors: tuple[int, ...]) -> tuple[F32, NDArray[np.bool_]]:
        """The signal maps of ``sensors`` stacked (C, ny, nx) (all NaN for a sensor without
        one) and which have one; cached per sensor tuple."""
        cache: dict[tuple[int, ...], tuple[F32, NDArray[np.bool_]]] = self.__dict__.setdefault(
            "_signal_stacks", {}
        )
        hit = cache.get(sensors)
        if hit is None:
            ny, nx = self.total.shape
            stack = np.full((len(sensors), ny, nx), np.nan, dtype=np.float32)
            has = np.zeros(len(sensors), dtype=bool)
            for c, row in enumerate(sensors):
                if row in self.signal:
                    stack[c], has[c] = self.signal[row], True
            hit = cache[sensors] = (stack, has)
        return hit

    def body_totals(
        self,
        outline_xy: F64,
        subset: tuple[int, ...],
        n_bins: int,
        order: tuple[int, ...] | None = None,
        keep: tuple[int, ...] = (),
    ) -> F32:
        """(H, ny, nx) fused ln(1 - Pd) of target *bodies* for ``n_bins`` relative headings
        (bin h: h * pi / H rad; a box is symmetric under a half turn), over the sensor rows
        ``subset``: per sensor, its ``body_layer`` (the ``order[i]``-th best ln(1 - Pd) of
        its layer over the body's footprint outline ``outline_xy``, (K, 2) m, target
        frame), summed over the sensors (in float64, in ``subset`` order). A proposal for
        the search only: it ignores the facing side, the height of the samples and the
        visible part's cross-section, which the exact evaluation (``coverage.body``)
        applies (error measured in ``sensorgap tradeoff``). Cached per (outline, subset,
        bins, order); the layers of the rows in ``keep`` stay cached too (a glared
        camera's part is taken out again along the tracks, ``_outline_layer``)."""
        order = order or (0,) * len(subset)
        key = (outline_xy.tobytes(), subset, n_bins, order)
        cache: dict[tuple[bytes, tuple[int, ...], int, tuple[int, ...]], F32] = (
            self.__dict__.setdefault("_body_totals", {})
        )
        hit = cache.get(key)
        if hit is not None:
            return hit
        out = np.zeros((n_bins, *self.total.shape), dtype=np.float64)
        for row, k in zip(subset, order, strict=True):
            part = (
                self.body_layer(outline_xy, row, n_bins, k)
                if row in keep
                else self._body_layer(outline_xy, row, n_bins, k)
            )
            if part is not None:
                cy, cx = part.values.shape[1:]
                out[:, part.j0 : part.j0 + cy, part.i0 : part.i0 + cx] += part.values
        hit = cache[key] = out.astype(np.float32)
        return hit

    def body_layer(self, outline_xy: F64, row: int, n_bins: int, k: int) -> BodyLayer | None:
        """One sensor's part of the body maps (cached; see ``_body_layer``)."""
        key = (outline_xy.tobytes(), row, n_bins, k)
        cache: dict[tuple[bytes, int, int, int], BodyLayer | None] = self.__dict__.setdefault(
            "_body_layers", {}
        )
        if key not in cache:
            cache[key] = self._body_layer(outline_xy, row, n_bins, k)
        return cache[key]

    def _body_layer(self, outline_xy: F64, row: int, n_bins: int, k: int) -> BodyLayer | None:
        """Sensor ``row``'s part of the body maps: per heading bin, the ``k``-th best (0:
        the smallest) ln(1 - Pd) of its layer over the outline rotated to the bin and
        rounded to whole cells (``_outline_offsets``; k = 0 is a morphological erosion,
        any outline point seen; a higher k asks for that many outline points, the
        lookup's stand-in for a minimum visible fraction). Computed on the crop where it
        can be non-zero (the sensor's non-zero cells grown by the outline's reach);
        ``None`` if the sensor sees nothing on this map."""
        layer = self.layers[row]
        rows_any = np.flatnonzero(np.any(layer < 0.0, axis=1))
        if rows_any.size == 0:
            return None
        cols_any = np.flatnonzero(np.any(layer < 0.0, axis=0))
        ny, nx = layer.shape
        ox, oy = _outline_offsets(outline_xy, n_bins, self.grid.resolution)
        px, py = int(np.max(np.abs(ox))), int(np.max(np.abs(oy)))
        j0, j1 = max(int(rows_any[0]) - py, 0), min(int(rows_any[-1]) + 1 + py, ny)
        i0, i1 = max(int(cols_any[0]) - px, 0), min(int(cols_any[-1]) + 1 + px, nx)
        cy, cx = j1 - j0, i1 - i0
        padded = np.pad(layer[j0:j1, i0:i1], ((py, py), (px, px)))
        values = np.empty((n_bins, cy, cx), dtype=np.float32)
        for h in range(n_bins):
            offs = list(zip(ox[h].tolist(), oy[h].tolist(), strict=True))
            if k == 0:
                best = np.zeros((cy, cx), dtype=np.float32)
                for dx, dy in set(offs):
                    np.minimum(
                        best, padded[py + dy : py + dy + cy, px + dx : px + dx + cx], out=best
                    )
                values[h] = best
            else:
                shifted = [
                    padded[py + dy : py + dy + cy, px + dx : px + dx + cx] for dx, dy in offs
                ]
                values[h] = np.partition(np.stack(shifted), k, axis=0)[k]
        return BodyLayer(j0, i0, values)

    def near_view(self, sensors: tuple[int, ...], pad: float) -> NDArray[np.bool_]:
        """``fastlookup.near_view_mask`` of the signal maps of ``sensors`` for a body of
        reach ``pad`` (m), rounded up to whole cells plus one; (1, 1, 1) False when
        ``pad`` is 0 (unused). Cached per (sensors, pad)."""
        if pad <= 0.0:
            return np.zeros((1, 1, 1), dtype=bool)
        cache: dict[tuple[tuple[int, ...], float], NDArray[np.bool_]] = self.__dict__.setdefault(
            "_near_view", {}
        )
        hit = cache.get((sensors, pad))
        if hit is None:
            stack, _ = self.signal_stack(sensors)
            cells = int(math.ceil(pad / self.grid.resolution)) + 1
            hit = cache[(sensors, pad)] = near_view_mask(stack, cells)
        return hit

    @property
    def nbytes(self) -> int:
        """Memory held by the maps, bytes."""
        extra = [
            *self.__dict__.get("_body_totals", {}).values(),
            *self.__dict__.get("_near_view", {}).values(),
        ]
        return int(
            self.layers.nbytes
            + self.total.nbytes
            + sum(v.nbytes for v in self.signal.values())
            + sum(v.nbytes for v in extra)
        )

    def interpolate_signal(self, sensor: int, x: F64, y: F64) -> tuple[F64, NDArray[np.int8]]:
        """Bilinear received signal (dB) of a glare-prone sensor and the state of each
        point (see ``_bilinear``: 1 interpolated, 0 out of view, 2 edge)."""
        return self._at(self.signal[sensor], x, y, True)

    def interpolate(self, layer: int | None, x: F64, y: F64) -> tuple[F64, NDArray[np.bool_]]:
        """Bilinear value of one layer (``None``: the total) at vehicle-frame points (m),
        and whether each point lies inside the map (outside: value 0)."""
        out, inside = self._at(self.total if layer is None else self.layers[layer], x, y, False)
        return out, inside == 1

    def _at(self, img: F32, x: F64, y: F64, finite: bool) -> tuple[F64, NDArray[np.int8]]:
        return interpolate_map(self.grid, img, x, y, finite)


def lookup_log_miss(
    maps: LogMissMaps, scene: Scene, x: F64, y: F64, z: F64, sun_dirs: F64 | None = None
) -> tuple[F64, int]:
    """Fused ln P_miss at flat points (m) from the maps, exact where the maps cannot
    answer (outside the map; glared cameras). Returns the values and how many point-sensor
    pairs were evaluated exactly."""
    total, inside = maps.interpolate(None, x, y)
    n_exact = 0
    out = np.where(inside, total, 0.0)
    outside = np.flatnonzero(~inside)
    if outside.size:
        sd = None if sun_dirs is None else sun_dirs[outside]
        out[outside] = exact_log_miss(scene, x[outside], y[outside], z[outside], sd)
        n_exact += outside.size * len(scene.sensors)
    if sun_dirs is None:
        return out, n_exact
    ins = np.flatnonzero(inside)
    for row, s in enumerate(scene.sensors):
        prepared = scene.prepared(s)
        if prepared.snr_db_glare is None:
            continue
        w = s.model.glare_weights(s.mount, sun_dirs[ins])
        g = ins[w > 0.0]
        if g.size == 0:
            continue

        def exact_edge(edge: NDArray[np.int64], g: IntArr = g, s: Sensor = s) -> F64:
            ge = g[edge]
            return sensor_log_miss(scene, s, x[ge], y[ge], z[ge], sun_dirs[ge])

        centres = _centres(x[g], y[g], z[g], sun_dirs[g], w[w > 0.0])
        change, k = _glare_change(maps, scene, row, centres, exact_edge)
        out[g] += change
        n_exact += k
    return out, n_exact


@dataclass(frozen=True)
class _Cones:
    """The glare cones of a scene's glare-prone cameras, stacked for ``lookup_pass``."""

    sensors: tuple[int, ...]
    rot: F64
    half_h: F64
    half_v: F64
    margin: F64
    cos_bound: F64
    yaw: F64
    level: NDArray[np.bool_]
    mount_xy: F64
    max_range: F64


def _cones(scene: Scene, subset: frozenset[int] | None = None) -> _Cones | None:
    """The scene's glare cones (of the sensor rows in ``subset``, default all), or ``None``
    if a glare-prone sensor has no cone form; cached on the scene per subset."""
    cache: dict[frozenset[int] | None, _Cones | None] = scene.__dict__.setdefault(
        "_glare_cones", {}
    )
    if subset not in cache:
        cache[subset] = _cones_of(scene, subset)
    return cache[subset]


def _cones_of(scene: Scene, subset: frozenset[int] | None) -> _Cones | None:
    """``_cones`` computed."""
    rows, cones = [], []
    for row, s in enumerate(scene.sensors):
        if subset is not None and row not in subset:
            continue
        if scene.prepared(s).snr_db_glare is None:
            continue
        cone = s.model.glare_cone(s.mount)
        if cone is None:
            return None
        rows.append(row)
        cones.append(cone)
    hh = np.array([c.half_h for c in cones], dtype=np.float64)
    hv = np.array([c.half_v for c in cones], dtype=np.float64)
    mg = np.array([c.margin for c in cones], dtype=np.float64)
    return _Cones(
        tuple(rows),
        np.ascontiguousarray(
            np.array([c.rotation for c in cones], dtype=np.float64).reshape(-1, 3, 3)
        ),
        hh,
        hv,
        mg,
        np.array([cone_cos_bound(a, b, m) for a, b, m in zip(hh, hv, mg, strict=True)]),
        np.array([c.yaw for c in cones], dtype=np.float64),
        np.array([c.pitch == 0.0 for c in cones], dtype=bool),
        np.array(
            [[scene.sensors[r].mount.x, scene.sensors[r].mount.y] for r in rows], dtype=np.float64
        ).reshape(-1, 2),
        np.array([scene.sensors[r].mount.max_range for r in rows], dtype=np.float64),
    )


#: Evaluates points exactly: flat indices into the (B, T) tracks -> fused ln P_miss.
ExactPoints = Callable[[NDArray[np.int64]], F64]
#: Evaluates one camera exactly: (sensor row, flat indices) -> its ln(1 - Pd).
ExactCamera = Callable[[int, NDArray[np.int64]], F64]


@dataclass(frozen=True)
class TrackLookup:
    """What ``lookup_log_miss_tracks`` looks up besides the point maps: (H, ny, nx) fused
    maps per bin of relative target heading (``totals``, see ``fastlookup.lookup_pass``)
    with the (B, T) relative heading of every step (``psi``, rad), the sensor rows fused
    (``subset``; their glare corrections only) and exact evaluators for points off the map
    and glared cameras at the edge of their view."""

    totals: F32
    psi: F64
    subset: frozenset[int] | None
    exact_points: ExactPoints
    exact_camera: ExactCamera
    #: (K, 2) footprint outline of a target body (target frame, m); with it a glared
    #: camera's layer is replaced over the outline (its ``order``-th best outline point,
    #: as the body maps), and cameras whose view the outline may reach are listed too
    outline: F64 | None = None
    #: sensor row -> order statistic over the outline (see ``LogMissMaps.body_totals``)
    order: dict[int, int] | None = None


def lookup_log_miss_tracks(
    maps: LogMissMaps,
    scene: Scene,
    x: F64,
    y: F64,
    heading: F64,
    n: NDArray[np.int64],
    rows: NDArray[np.int64],
    sun: F64,
    out: F64,
    how: TrackLookup | None = None,
    also: tuple[TrackLookup, NDArray[np.bool_], F64] | None = None,
) -> int:
    """``lookup_log_miss`` along (B, T) tracks in one compiled pass (``fastlookup``):
    writes the fused ln P_miss of the first ``n[r]`` steps of each row r in ``rows`` into
    ``out`` (B, T). ``x``, ``y``: vehicle-frame target positions (m); ``heading``: ego
    heading (rad); ``sun`` (B, 3): per row (kind, azimuth rad, elevation rad), see
    ``fastlookup.SUN_*``. Without ``how`` (point targets, every sensor) the values equal
    ``lookup_log_miss`` at the same points (up to rounding); with it, the maps, sensors and
    exact evaluators of ``how`` (target bodies, ``search.evaluate``). ``also`` = (lookup,
    at, also_out): the fused ln P_miss of a second sensor set with no glare-prone sensor
    (``also_glare_free``), in the same pass, into ``also_out`` (B, T) at the steps where
    ``at`` (B, T) holds (elsewhere left as it is); the caller adds it (a reaction model's
    moving-only sensors). Returns how many point-sensor pairs were evaluated exactly."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    heading = np.ascontiguousarray(heading, dtype=np.float64)
    if not out.flags.c_contiguous:
        raise ValueError("out must be C-contiguous")
    z0 = maps.grid.height
    t = x.shape[1]
    xf, yf, hf, of = x.reshape(-1), y.reshape(-1), heading.reshape(-1), out.reshape(-1)

    def dirs_at(flat: NDArray[np.int64]) -> F64:
        return sun_directions_at(sun, hf, flat, t)

    if how is None:
        exact_points, exact_camera = point_evaluators(scene, xf, yf, z0, dirs_at)
        how = TrackLookup(maps.total[None], np.zeros(x.shape), None, exact_points, exact_camera)
    cones = _cones(scene, how.subset)
    rows = np.ascontiguousarray(rows, dtype=np.int64)
    also_total, also_at, also_out = _no_also(maps) if also is None else _also_arrays(scene, also)
    if cones is None:  # a glare model without a cone form: exact along the whole tracks
        rr = np.repeat(rows, n[rows])
        kk = np.arange(rr.size) - np.repeat(np.cumsum(n[rows]) - n[rows], n[rows])
        flat = rr * t + kk
        of[flat] = how.exact_points(flat)
        return int(flat.size * len(scene.sensors)) + _also_exact(also, flat)
    n_pts = int(np.sum(n[rows]))
    n_cam = len(cones.sensors)
    pad = (
        0.0
        if how.outline is None
        else float(np.max(np.hypot(how.outline[:, 0], how.outline[:, 1])))
    )
    outside = np.empty(n_pts, dtype=np.int64)
    glare_idx = np.empty((n_cam, n_pts), dtype=np.int64)
    glare_w = np.empty((n_cam, n_pts), dtype=np.float64)
    glare_state = np.empty((n_cam, n_pts), dtype=np.int8)
    counts = np.zeros(1 + n_cam, dtype=np.int64)
    g = maps.grid
    signal, has_signal = maps.signal_stack(cones.sensors)
    lookup_pass(
        how.totals,
        *g.lookup_origin(),
        x,
        y,
        heading,
        np.ascontiguousarray(how.psi, dtype=np.float64),
        np.ascontiguousarray(n, dtype=np.int64),
        rows,
        np.ascontiguousarray(sun, dtype=np.float64),
        cones.rot,
        cones.half_h,
        cones.half_v,
        cones.margin,
        cones.cos_bound,
        cones.yaw,
        cones.level,
        cones.mount_xy,
        (cones.max_range + 1.5 * g.resolution + pad) ** 2,
        signal,
        has_signal,
        pad > 0.0,
        maps.near_view(cones.sensors, pad),
        also_total,
        also_at,
        also_out,
        out,
        outside,
        glare_idx,
        glare_w,
        glare_state,
        counts,
    )
    n_exact = 0
    if counts[0]:
        o = outside[: counts[0]]
        of[o] = how.exact_points(o)
        n_exact += o.size * len(scene.sensors) + _also_exact(also, o)
    for c, row in enumerate(cones.sensors):
        m = int(counts[1 + c])
        if m == 0:
            continue
        gi, wg = glare_idx[c, :m], glare_w[c, :m]
        xs, ys = xf[gi], yf[gi]
        sd = dirs_at(gi)
        if how.outline is not None:
            # a body: where its centre is not well inside the camera's view, the glared
            # layer is replaced over the outline; elsewhere at the centre (below). The body
            # maps' camera part and these differ slightly: ln P_miss stays <= 0
            st = glare_state[c, :m]
            e = np.flatnonzero(st != 1)
            if e.size:
                of[gi[e]] = np.minimum(
                    of[gi[e]]
                    + _glared_outline(maps, scene, row, gi[e], wg[e], xf, yf, how, sd[e], z0),
                    0.0,
                )
            keep = np.flatnonzero(st == 1)  # all four cells in view (lookup_pass)
            if keep.size:
                layer = _outline_layer(maps, row, gi[keep], xf, yf, how)
                new, _ = _glared_from_maps(
                    maps, scene, row, _centres(xs[keep], ys[keep], z0, sd[keep], wg[keep])
                )
                of[gi[keep]] = np.minimum(of[gi[keep]] + new - layer, 0.0)
            continue

        def exact_edge(edge: NDArray[np.int64], gi: NDArray[np.int64] = gi, row: int = row) -> F64:
            return how.exact_camera(row, gi[edge])

        change, k = _glare_change(maps, scene, row, _centres(xs, ys, z0, sd, wg), exact_edge)
        of[gi] += change  # each point at most once per camera
        n_exact += k
    return n_exact


def also_glare_free(scene: Scene, subset: tuple[int, ...]) -> bool:
    """Whether the sensor rows ``subset`` hold no glare-prone sensor (their lookup needs no
    glare correction: ``lookup_log_miss_tracks``'s ``also``)."""
    return all(scene.prepared(scene.sensors[i]).snr_db_glare is None for i in subset)


def _no_also(maps: LogMissMaps) -> tuple[F32, NDArray[np.bool_], F64]:
    """``lookup_pass``'s arguments for no second sensor set."""
    ny, nx = maps.total.shape
    return np.zeros((0, ny, nx), dtype=np.float32), np.zeros((1, 1), bool), np.zeros((1, 1))


def _also_arrays(
    scene: Scene, also: tuple[TrackLookup, NDArray[np.bool_], F64]
) -> tuple[F32, NDArray[np.bool_], F64]:
    """``lookup_pass``'s arguments for a second sensor set (``lookup_log_miss_tracks``)."""
    how, at, out = also
    if how.subset is None or not also_glare_free(scene, tuple(how.subset)):
        raise ValueError("the second sensor set must be a subset without glare-prone sensors")
    if not out.flags.c_contiguous:
        raise ValueError("also_out must be C-contiguous")
    return how.totals, np.ascontiguousarray(at, dtype=np.bool_), out


def _also_exact(
    also: tuple[TrackLookup, NDArray[np.bool_], F64] | None, flat: NDArray[np.int64]
) -> int:
    """The second sensor set evaluated exactly at the flat track indices ``flat`` where it
    counts (off the map, or along whole tracks); returns the point-sensor pairs."""
    if also is None:
        return 0
    how, at, out = also
    f = flat[at.reshape(-1)[flat]]
    if f.size:
        out.reshape(-1)[f] = how.exact_points(f)
    return int(f.size * len(how.subset or ()))


def point_evaluators(
    scene: Scene,
    xf: F64,
    yf: F64,
    z0: float,
    dirs_at: Callable[[NDArray[np.int64]], F64],
    sensors: Sequence[Sensor] | None = None,
) -> tuple[ExactPoints, ExactCamera]:
    """Exact evaluators at the target centres of flat (B * T) tracks at height ``z0`` (m),
    with per-point sun directions ``dirs_at(flat)``: the fused ln P_miss of ``sensors``
    (default: all) and one camera's ln(1 - Pd)."""

    def exact_points(flat: NDArray[np.int64]) -> F64:
        return exact_log_miss(
            scene, xf[flat], yf[flat], np.full(flat.size, z0), dirs_at(flat), sensors
        )

    def exact_camera(row: int, flat: NDArray[np.int64]) -> F64:
        return sensor_log_miss(
            scene, scene.sensors[row], xf[flat], yf[flat], np.full(flat.size, z0), dirs_at(flat)
        )

    return exact_points, exact_camera


def _outline_points(
    how: TrackLookup, gi: NDArray[np.int64], which: NDArray[np.int64], xf: F64, yf: F64
) -> tuple[F64, F64]:
    """Vehicle-frame outline points ``which`` of the flat (M * K) outline points of the
    bodies at flat track indices ``gi`` (point q: body q // K, outline point q % K)."""
    assert how.outline is not None
    k = len(how.outline)
    body, corner = gi[which // k], which % k
    psi = how.psi.reshape(-1)[body]
    c, sn = np.cos(psi), np.sin(psi)
    ox, oy = how.outline[corner, 0], how.outline[corner, 1]
    return xf[body] + c * ox - sn * oy, yf[body] + sn * ox + c * oy


def _order_stat(values: F64, k: int, how: TrackLookup, row: int) -> F64:
    """Per body (rows of K outline values): the ``how.order[row]``-th smallest."""
    q = 0 if how.order is None else how.order.get(row, 0)
    return np.asarray(np.partition(values.reshape(-1, k), q, axis=1)[:, q], dtype=np.float64)


def _glared_outline(
    maps: LogMissMaps,
    scene: Scene,
    row: int,
    gi: NDArray[np.int64],
    wg: F64,
    xf: F64,
    yf: F64,
    how: TrackLookup,
    sun_dirs: F64,
    z0: float,
) -> F64:
    """Body lookup of a glared camera: the change of its ln(1 - Pd) when its part of the
    body maps (``_outline_layer``) is replaced by the glared layer's best point of the
    body's outline (the same order statistic); outline points at the edge of its view
    exactly. ``sun_dirs``: (M, 3) vehicle-frame sun directions of the bodies at ``gi``."""
    assert how.outline is not None
    s = scene.sensors[row]
    psi = how.psi.reshape(-1)[gi]
    bodies = _bodies(xf[gi], yf[gi], psi, z0, sun_dirs, wg)
    vals, state = _glared_values(maps, scene, row, bodies, how.outline)
    new, k = vals.reshape(-1), len(how.outline)
    edge = np.flatnonzero(state.reshape(-1) == 2)
    if edge.size:
        px, py = _outline_points(how, gi, edge, xf, yf)
        new[edge] = sensor_log_miss(scene, s, px, py, np.full(edge.size, z0), sun_dirs[edge // k])
    return _order_stat(new, k, how, row) - _outline_layer(maps, row, gi, xf, yf, how)


def _outline_layer(
    maps: LogMissMaps, row: int, gi: NDArray[np.int64], xf: F64, yf: F64, how: TrackLookup
) -> F64:
    """A camera's part of the body maps ``how.totals`` at flat track indices: its
    ``LogMissMaps.body_layer`` (the ``how.order``-th best of its layer over the outline
    rotated to the step's heading bin and rounded to whole cells), interpolated
    bilinearly at the target's centre as the totals are: subtracting it removes this
    camera from the interpolated total up to float32 rounding. (Re-interpolating the
    layer at the outline points instead differed by up to 33 nepers where a detection is
    near certain, leaving a glared camera at Pd 0.97 where exact evaluation gave 0.006.)"""
    assert how.outline is not None
    g = maps.grid
    part = maps.body_layer(
        how.outline, row, how.totals.shape[0], 0 if how.order is None else how.order.get(row, 0)
    )
    out = np.zeros(gi.size)
    if part is not None:
        ny, nx = maps.total.shape
        body_layer_pass(
            part.values,
            part.j0,
            part.i0,
            ny,
            nx,
            *g.lookup_origin(),
            np.ascontiguousarray(xf[gi]),
            np.ascontiguousarray(yf[gi]),
            np.ascontiguousarray(how.psi.reshape(-1)[gi], dtype=np.float64),
            out,
        )
    return out


@functools.lru_cache(maxsize=64)
def _outline_offsets_cached(
    outline: bytes, k: int, n_bins: int, res: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    xy = np.frombuffer(outline, dtype=np.float64).reshape(k, 2)
    a = np.arange(n_bins) * math.pi / n_bins
    ox = np.rint(
        (np.cos(a)[:, None] * xy[None, :, 0] - np.sin(a)[:, None] * xy[None, :, 1]) / res
    ).astype(np.int64)
    oy = np.rint(
        (np.sin(a)[:, None] * xy[None, :, 0] + np.cos(a)[:, None] * xy[None, :, 1]) / res
    ).astype(np.int64)
    return ox, oy


def _outline_offsets(
    outline: F64, n_bins: int, res: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(H, K) whole-cell offsets of a (K, 2) outline (m) rotated to each of ``n_bins``
    heading bins (bin h: h * pi / H rad), as ``LogMissMaps.body_totals`` rounds them."""
    xy = np.ascontiguousarray(outline, dtype=np.float64)
    return _outline_offsets_cached(xy.tobytes(), len(xy), n_bins, float(res))
