"""Targets as bodies: what each sensor sees of a target's box decides its detection.

A target is its box (``length_m`` x ``width_m`` x ``height_m`` of ``targets.toml``, centred
on its reference point on the ground) at a heading. Its outline is sampled on the four
vertical faces (``BodySamples``: at most ``SPACING_M`` apart along each face, at
``HEIGHT_FRACTIONS`` of the height). For one sensor and one target pose:

* the *facing* samples are those on faces whose outward normal points towards the sensor's
  mount (the half of the outline a sensor can possibly see; a box has 1 or 2 such faces);
* a facing sample is *visible* when it lies inside the sensor's 3D field of view and range
  and the straight segment from the mount to it does not pass through the ego's own body
  (the ego's box from the vehicle file, shrunk by ``EGO_SHRINK_M``; sensors mounted inside
  that box, e.g. behind the windscreen, are never hidden by it);
* the visible fraction ``v = visible / facing`` and the SNR of the visible part,
  ``SNR_body = max over visible samples of SNR(sample) + 10 log10(v)`` (the strongest
  point, with the cross-section scaled by the visible fraction: every model's SNR is
  linear in the cross-section, eq. 1, 4, 6);
* detection rule per sensor type (``MIN_VISIBLE_FRACTION``): Pd = ROC(SNR_body) when
  ``v`` reaches the type's minimum visible fraction, else 0.

The minimum fractions (estimates, with their anchors): camera 0.5 — image detectors lose
most of their recall once more than about a third to a half of the object is hidden
(Dollar et al., "Pedestrian detection: an evaluation of the state of the art", IEEE TPAMI
2012, Fig. 9: "heavy occlusion" 35-80 % drops the log-average miss rate to 0.9+); lidar 0.1
— a cluster needs a handful of returns on the object (estimate: ~3 of the ~30 samples);
radar and ultrasonic: any reflecting part in the beam (v > 0).

Sun glare acts per sample (each sample's per-step sun direction), as for points.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgap.config.target import TargetConfig
from sensorgap.coverage.fastlookup import place
from sensorgap.coverage.grid import GridCoverage, GridSpec
from sensorgap.coverage.logmiss import log_miss_of, sensor_snr
from sensorgap.coverage.occluders import COLUMNS as OCC_COLUMNS
from sensorgap.coverage.occluders import hidden_by_boxes
from sensorgap.coverage.scene import Scene
from sensorgap.jit import njit
from sensorgap.models.roc import detection_probability
from sensorgap.models.system import Sensor

F64 = NDArray[np.float64]

#: Largest distance between outline samples along a face, m (estimate: a quarter of a
#: car's width; 20-40 samples per body).
SPACING_M = 1.2
#: Heights of the samples as fractions of the target's height (estimate: lower and upper
#: part of the body; a car's bumper/sill line and its glasshouse).
HEIGHT_FRACTIONS = (0.25, 0.75)
#: The ego's own box is shrunk by this much before testing rays against it, m (mounts sit
#: on its surface).
EGO_SHRINK_M = 0.05
#: Minimum visible fraction of the facing outline per sensor type (see the module text).
MIN_VISIBLE_FRACTION: dict[str, float] = {
    "camera": 0.5,
    "lidar": 0.1,
    "radar": 0.0,
    "ultrasonic": 0.0,
}
#: For sensor types not listed above.
DEFAULT_MIN_VISIBLE_FRACTION = 0.0
#: Skip poses whose outline cannot reach a sensor's range or horizontal field of view
#: before evaluating their samples (identical results; tests switch it off to compare).
CULL = True


@dataclass(frozen=True)
class BodySamples:
    """Outline samples of a target box in its own frame (x forward, y left, z up; origin
    on the ground below the box centre), m.

    Attributes:
        x, y, z: (K,) sample positions, m.
        nx, ny: (K,) outward unit normal of the face each sample lies on.
    """

    x: F64
    y: F64
    z: F64
    nx: F64
    ny: F64

    def __len__(self) -> int:
        return len(self.x)


@cache
def _samples(length: float, width: float, height: float) -> BodySamples:
    xs, ys, nxs, nys = [], [], [], []
    hl, hw = 0.5 * length, 0.5 * width
    for cx, cy, nx, ny, span, along_x in (
        (hl, 0.0, 1.0, 0.0, width, False),
        (-hl, 0.0, -1.0, 0.0, width, False),
        (0.0, hw, 0.0, 1.0, length, True),
        (0.0, -hw, 0.0, -1.0, length, True),
    ):
        k = max(1, math.ceil(span / SPACING_M))
        u = (np.arange(k) + 0.5) / k * span - 0.5 * span
        xs.append(cx + (u if along_x else 0.0 * u))
        ys.append(cy + (0.0 * u if along_x else u))
        nxs.append(np.full(k, nx))
        nys.append(np.full(k, ny))
    bx, by = np.concatenate(xs), np.concatenate(ys)
    bnx, bny = np.concatenate(nxs), np.concatenate(nys)
    nh = len(HEIGHT_FRACTIONS)
    z = np.repeat(np.asarray(HEIGHT_FRACTIONS) * height, bx.size)
    return BodySamples(np.tile(bx, nh), np.tile(by, nh), z, np.tile(bnx, nh), np.tile(bny, nh))


def body_samples(target: TargetConfig) -> BodySamples:
    """The outline samples of a target class (cached per size)."""
    return _samples(float(target.length_m), float(target.width_m), float(target.height_m))


def min_visible_fraction(sensor: Sensor) -> float:
    """The sensor type's minimum visible fraction of the facing outline."""
    return MIN_VISIBLE_FRACTION.get(sensor.type_name, DEFAULT_MIN_VISIBLE_FRACTION)


def _ego_box(scene: Scene) -> tuple[F64, F64]:
    """The ego's box shrunk by ``EGO_SHRINK_M``: (lo, hi) corners, vehicle frame, m."""
    v = scene.system.config.vehicle
    lo = np.array([v.x_rear_m + EGO_SHRINK_M, -0.5 * v.width_m + EGO_SHRINK_M, EGO_SHRINK_M])
    hi = np.array(
        [v.x_front_m - EGO_SHRINK_M, 0.5 * v.width_m - EGO_SHRINK_M, v.height_m - EGO_SHRINK_M]
    )
    return lo, hi


def _inside(sensor: Sensor, lo: F64, hi: F64) -> bool:
    """Whether the sensor's mount lies strictly inside the ego's box ``lo``..``hi`` (m,
    ``_ego_box``): then the box never hides a sample from it."""
    m = sensor.mount
    p = np.array([m.x, m.y, m.z])
    return bool(np.all(p > lo) and np.all(p < hi))


@njit(nogil=True, inline="always")
def facing_offset(
    nx: float, ny: float, px: float, py: float, vx: float, vy: float
) -> float:  # pragma: no cover - compiled
    """How much an outline sample at (``px``, ``py``) on a face with outward horizontal
    normal (``nx``, ``ny``) faces the point (``vx``, ``vy``) (a mount or a viewpoint), m:
    the offset to the point along the normal; > 0 facing it, <= 0 looking away."""
    return (vx - px) * nx + (vy - py) * ny


@njit(nogil=True)
def _hidden_by_box(
    ox: float, oy: float, oz: float, px: float, py: float, pz: float, lo: F64, hi: F64
) -> bool:  # pragma: no cover - compiled
    """True when the segment from ``o`` (a sensor's mount) to ``p`` (a sample) passes
    through the axis-aligned box ``lo``..``hi`` (the ego's own body; slab test), m."""
    o = (ox, oy, oz)
    p = (px, py, pz)
    t0, t1 = 0.0, 1.0
    for a in range(3):
        d = p[a] - o[a]
        if d == 0.0:
            if o[a] <= lo[a] or o[a] >= hi[a]:
                return False
            continue
        ta = (lo[a] - o[a]) / d
        tb = (hi[a] - o[a]) / d
        t0 = max(t0, min(ta, tb))
        t1 = min(t1, max(ta, tb))
    return t0 < t1


@njit(nogil=True, inline="always")
def _sample_in_view(
    x: float,
    y: float,
    z: float,
    mount: F64,
    lo: F64,
    hi: F64,
    check_ego: bool,
    prefilter: bool,
) -> bool:  # pragma: no cover - compiled
    """Whether a sample at (``x``, ``y``, ``z``), m, that faces the mount (the callers test
    that first, ``facing_offset``) is in view of one sensor: ``_view_kernel``'s remaining
    tests without the occluders (loose field-of-view and range test, the ego's own
    box)."""
    mx, my, mz = mount[0], mount[1], mount[2]
    ddx = x - mx
    ddy = y - my
    ddz = z - mz
    if prefilter:
        r2 = ddx * ddx + ddy * ddy + ddz * ddz
        if r2 > (mount[10] * (1.0 + 1e-9) + 1e-9) ** 2 or r2 < (mount[9] * (1.0 - 1e-9)) ** 2:
            return False
        cy, sy, cp, sp = mount[3], mount[4], mount[5], mount[6]
        tan_h, tan2_v, half_h = mount[7], mount[8], mount[11]
        u = cy * ddx + sy * ddy
        v = -sy * ddx + cy * ddy
        xs = cp * u - sp * ddz
        zs = sp * u + cp * ddz
        slack = 1e-9 * (abs(xs) + abs(v) + abs(zs)) + 1e-12
        if tan_h >= 0.0:
            if not (xs > -slack and abs(v) <= xs * tan_h + slack):
                return False
        elif half_h < math.pi and half_h > 0.5 * math.pi:
            if xs < -slack and abs(v) < -xs * math.tan(math.pi - half_h) - slack:
                return False
        elif half_h == 0.5 * math.pi and xs < -slack:
            return False
        if tan2_v >= 0.0 and zs * zs > (xs * xs + v * v) * tan2_v * (1.0 + 1e-9) + slack:
            return False
    return not (check_ego and _hidden_by_box(mx, my, mz, x, y, z, lo, hi))


@njit(nogil=True)
def _view_kernel(
    px: F64,
    py: F64,
    pz: F64,
    nx: F64,
    ny: F64,
    near: NDArray[np.int64],
    mount: F64,
    lo: F64,
    hi: F64,
    check_ego: bool,
    prefilter: bool,
    occ: F64,
    flat: NDArray[np.int64],
    n_face: NDArray[np.int64],
) -> int:  # pragma: no cover - compiled
    """The samples of the ``near`` poses of (N, K) arrays that one sensor may see: facing
    its mount, not behind the ego's box (``_hidden_by_box``), passing a slightly loose
    field-of-view and range test (the exact test follows in ``sensor_snr``; the slack only
    keeps rounding from dropping a sample it would keep; ``prefilter`` False: no such
    test) and not hidden by an occluder (``occ``: (P, M, 7) rows of
    ``occluders.COLUMNS``, P = 1 for all poses or one set per pose). ``mount`` = (x, y, z,
    cos yaw, sin yaw, cos pitch, sin pitch, tan half hfov or -1 (>= 90 deg), tan^2 half
    vfov or -1 (>= 90 deg), min range, max range, half hfov). Writes flat indices (pose * K
    + sample) into ``flat`` and the facing count per near pose into ``n_face``; returns
    how many were written."""
    k = px.shape[1]
    mx, my, mz = mount[0], mount[1], mount[2]
    m = 0
    for q in range(near.size):
        i = near[q]
        nf = 0
        for j in range(k):
            # facing the mount (counted), then the cheaper of the two remaining rejections
            # first: hidden by an occluder, out of view (the same samples are kept)
            if facing_offset(nx[i, j], ny[i, j], px[i, j], py[i, j], mx, my) <= 0.0:
                continue
            nf += 1
            if occ.shape[1] and hidden_by_boxes(
                mx, my, mz, px[i, j], py[i, j], pz[i, j], occ[i if occ.shape[0] > 1 else 0]
            ):
                continue
            if not _sample_in_view(
                px[i, j], py[i, j], pz[i, j], mount, lo, hi, check_ego, prefilter
            ):
                continue
            flat[m] = q * k + j
            m += 1
        n_face[q] = nf
    return m


@njit(nogil=True, inline="always")
def _pose_near(
    cx: float, cy: float, rad: float, mount: F64, hfov: float, pitch: float, cull: bool
) -> bool:  # pragma: no cover - compiled
    """``_near_poses`` for one pose (centre ``cx``, ``cy``, outline radius ``rad``, m) and
    one sensor (``mount``: the ``_mount_row``, its full ``hfov`` and ``pitch``, rad)."""
    if not cull:
        return True
    dx, dy = cx - mount[0], cy - mount[1]
    d2 = dx * dx + dy * dy
    reach = mount[10] + rad
    if d2 > reach * reach:
        return False
    if hfov < 2.0 * math.pi and abs(pitch) < 0.5:
        dist = math.sqrt(d2)
        if dist <= rad:
            return True
        yaw = math.atan2(mount[4], mount[3])
        off = abs(((math.atan2(dy, dx) - yaw + math.pi) % (2.0 * math.pi)) - math.pi)
        spread = math.asin(min(1.0, rad / max(dist, 1e-9)))
        return off - spread <= 0.5 * hfov + abs(pitch) + 0.05
    return True


@njit(nogil=True)
def _changes_kernel(
    px: F64,
    py: F64,
    pz: F64,
    nx: F64,
    ny: F64,
    cx: F64,
    cy: F64,
    rad: float,
    mount: F64,
    hfov: float,
    pitch: float,
    cull: bool,
    lo: F64,
    hi: F64,
    check_ego: bool,
    occ: F64,
    out: NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    """Marks in ``out`` the poses (not yet marked) where an occluder of ``occ`` ((N, M, 7)
    or (1, M, 7)) hides at least one sample that one sensor would otherwise see
    (``_sample_in_view`` with the loose prefilter): one pass, stopping at the first;
    poses whose outline cannot reach the sensor's range or field of view
    (``_pose_near``: their samples are all out of view) are skipped."""
    n, k = px.shape
    mx, my, mz = mount[0], mount[1], mount[2]
    for i in range(n):
        if out[i] or not _pose_near(cx[i], cy[i], rad, mount, hfov, pitch, cull):
            continue
        boxes = occ[i if occ.shape[0] > 1 else 0]
        for j in range(k):
            # the same conjunction as ``_view_kernel``'s, cheapest rejections first:
            # facing the mount, hidden by an occluder, then in view
            if facing_offset(nx[i, j], ny[i, j], px[i, j], py[i, j], mx, my) <= 0.0:
                continue
            if not hidden_by_boxes(mx, my, mz, px[i, j], py[i, j], pz[i, j], boxes):
                continue
            if _sample_in_view(px[i, j], py[i, j], pz[i, j], mount, lo, hi, check_ego, True):
                out[i] = True
                break


#: (N, K) sample positions x, y, z (m) and face normals nx, ny of N target poses
#: (``body_points``).
BodyPoints = tuple[F64, F64, F64, F64, F64]


@njit(nogil=True, inline="always")
def place_sample(
    x: float, y: float, c: float, s: float, bx: float, by: float, bnx: float, bny: float
) -> tuple[float, float, float, float]:  # pragma: no cover - compiled
    """One outline sample (``bx``, ``by``, m, with face normal ``bnx``, ``bny``; target
    frame) of a body posed at (``x``, ``y``), m, heading cosine ``c`` and sine ``s``: its
    position (m) and normal in the frame of the pose."""
    px, py = place(x, y, c, s, bx, by)
    return px, py, c * bnx - s * bny, s * bnx + c * bny


@njit(nogil=True)
def _points_kernel(
    x: F64,
    y: F64,
    cos: F64,
    sin: F64,
    bx: F64,
    by: F64,
    bz: F64,
    bnx: F64,
    bny: F64,
    px: F64,
    py: F64,
    pz: F64,
    nx: F64,
    ny: F64,
) -> None:  # pragma: no cover - compiled
    """Fills the (N, K) sample positions and normals of N poses (``body_points``; the
    same operations in the same order as the numpy expressions it replaced)."""
    for i in range(x.size):
        c, s = cos[i], sin[i]
        for j in range(bx.size):
            px[i, j], py[i, j], nx[i, j], ny[i, j] = place_sample(
                x[i], y[i], c, s, bx[j], by[j], bnx[j], bny[j]
            )
            pz[i, j] = bz[j]


def _scene_points(scene: Scene, x: F64, y: F64, psi: ArrayLike) -> BodyPoints:
    """``body_points`` of the scene's target class at the given poses."""
    return body_points(body_samples(scene.target), x, y, np.asarray(psi, dtype=np.float64))


def body_points(body: BodySamples, x: F64, y: F64, psi: F64) -> BodyPoints:
    """(N, K) vehicle-frame sample positions (m) and face normals of N target poses
    (centre x, y in m, heading psi in rad relative to the ego), C-contiguous."""
    x, y, psi = (np.ascontiguousarray(a, dtype=np.float64).ravel() for a in (x, y, psi))
    shape = (x.size, len(body))
    px, py, pz, nx, ny = (np.empty(shape) for _ in range(5))
    _points_kernel(
        x, y, np.cos(psi), np.sin(psi), body.x, body.y, body.z, body.nx, body.ny, px, py, pz, nx, ny
    )
    return px, py, pz, nx, ny


def take_points(points: BodyPoints, rows: NDArray[np.intp] | NDArray[np.bool_]) -> BodyPoints:
    """The ``rows`` (indices or a mask) of body points (``body_points``)."""
    px, py, pz, nx, ny = (np.ascontiguousarray(a[rows]) for a in points)
    return px, py, pz, nx, ny


def _near_poses(sensor: Sensor, cx: F64, cy: F64, rad: float) -> NDArray[np.bool_]:
    """(N,) the poses (centres ``cx``, ``cy``, outline radius ``rad``, m) whose outline can
    reach the sensor's range and horizontal field of view (a cheap, conservative cull
    before the samples; everything when ``CULL`` is off)."""
    m = sensor.mount
    reach = m.max_range + rad
    d2 = (cx - m.x) ** 2 + (cy - m.y) ** 2
    near_mask = d2 <= reach * reach
    if not CULL:
        near_mask[:] = True
    elif m.hfov < 2.0 * math.pi and abs(m.pitch) < 0.5:
        # and whose outline can reach the horizontal field of view (a pitched sensor's
        # azimuth differs from the vehicle-frame bearing by less than |pitch|: margin)
        dist = np.sqrt(d2)
        off = np.abs(
            np.mod(np.arctan2(cy - m.y, cx - m.x) - m.yaw + math.pi, 2.0 * math.pi) - math.pi
        )
        spread = np.arcsin(np.minimum(1.0, rad / np.maximum(dist, 1e-9)))
        near_mask &= (off - spread <= 0.5 * m.hfov + abs(m.pitch) + 0.05) | (dist <= rad)
    return np.asarray(near_mask)


def body_sensor_pd(
    scene: Scene,
    sensor: Sensor,
    cx: F64,
    cy: F64,
    px: F64,
    py: F64,
    pz: F64,
    nx: F64,
    ny: F64,
    sun_dirs: F64 | None = None,
    occluders: F64 | None = None,
) -> tuple[F64, F64]:
    """Pd of one sensor for N target bodies with centres ``cx``, ``cy`` (m) given as
    (N, K) samples (``body_points``) and the visible fraction of each body's facing
    outline; ``sun_dirs`` (N, 3) per pose (vehicle frame, NaN rows: no direct sun) or
    ``None``; ``occluders``: boxes hiding parts of the bodies (``coverage.occluders``):
    (M, 7) for every pose or (N, M, 7) per pose; ``None``: an empty road. Returns
    (pd, fraction), (N,)."""
    n, k = px.shape
    pd = np.zeros(n)
    frac = np.zeros(n)
    # poses whose outline can reach the sensor's range and field of view
    near = np.flatnonzero(_near_poses(sensor, cx, cy, _radius(px, py, cx, cy)))
    if near.size == 0:
        return pd, frac
    lo, hi = _ego_box(scene)
    mount = _mount_row(sensor)
    buf = np.empty(near.size * k, dtype=np.int64)
    n_face = np.empty(near.size, dtype=np.int64)
    cnt = _view_kernel(
        np.ascontiguousarray(px),
        np.ascontiguousarray(py),
        np.ascontiguousarray(pz),
        np.ascontiguousarray(nx),
        np.ascontiguousarray(ny),
        near.astype(np.int64),
        mount,
        lo,
        hi,
        not _inside(sensor, lo, hi),
        CULL,
        _occ3(occluders, n),
        buf,
        n_face,
    )
    if cnt == 0:
        return pd, frac
    flat = buf[:cnt]  # (near pose q) * K + sample
    src = near[flat // k] * k + flat % k  # into the full (N, K) arrays
    sd = None if sun_dirs is None else sun_dirs[near[flat // k]]
    idx, snr = sensor_snr(scene, sensor, px.ravel()[src], py.ravel()[src], pz.ravel()[src], sd)
    if idx.size == 0:
        return pd, frac
    pose = flat[idx] // k  # ascending: samples are listed pose by pose
    starts = np.flatnonzero(np.concatenate(([True], pose[1:] != pose[:-1])))
    seen = pose[starts]
    count = np.diff(np.append(starts, pose.size))
    best = np.full(near.size, -np.inf)
    best[seen] = np.maximum.reduceat(snr, starts)
    f = count / np.maximum(n_face[seen], 1)
    frac[near[seen]] = f
    keep = f >= max(min_visible_fraction(sensor), 1e-12)
    ok = seen[keep]
    if ok.size:
        snr_body = best[ok] + 10.0 * np.log10(f[keep])
        pd[near[ok]] = detection_probability(snr_body, sensor.roc, scene.roc_shift_db)
    return pd, frac


def occlusion_changes(
    scene: Scene,
    x: F64,
    y: F64,
    psi: F64,
    occluders: F64,
    sensors: Sequence[Sensor] | None = None,
    points: BodyPoints | None = None,
) -> NDArray[np.bool_]:
    """(N,) whether the (N, M, 7) ``occluders`` hide any facing, in-view sample of the
    target bodies at x, y (m), psi (rad) from any of ``sensors`` (default: all): geometry
    only (no SNR), so a caller can keep an occlusion-free value where they hide nothing.
    ``points``: the bodies' samples if the caller has them (``body_points``). Each sensor
    tests only the poses its range and field of view can reach (``_near_poses``: the
    samples of the others are out of view, so the answer is the same)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    px, py, pz, nx, ny = points if points is not None else _scene_points(scene, x, y, psi)
    out = np.zeros(px.shape[0], dtype=bool)
    lo, hi = _ego_box(scene)
    occ = _occ3(occluders, px.shape[0])
    if occ.shape[1] == 0 or px.shape[0] == 0:
        return out
    rad = _radius(px, py, x, y)
    for sensor in scene.sensors if sensors is None else sensors:
        m = sensor.mount
        _changes_kernel(
            px,
            py,
            pz,
            nx,
            ny,
            x,
            y,
            rad,
            _mount_row(sensor),
            float(m.hfov),
            float(m.pitch),
            CULL,
            lo,
            hi,
            not _inside(sensor, lo, hi),
            occ,
            out,
        )
    return out


def _mount_row(sensor: Sensor) -> F64:
    """A sensor's mount as the ``_view_kernel`` row."""
    m = sensor.mount
    half_h, half_v = 0.5 * m.hfov, 0.5 * m.vfov
    return np.array(
        [
            m.x,
            m.y,
            m.z,
            math.cos(m.yaw),
            math.sin(m.yaw),
            math.cos(m.pitch),
            math.sin(m.pitch),
            math.tan(half_h) if half_h < 0.5 * math.pi else -1.0,
            math.tan(half_v) ** 2 if half_v < 0.5 * math.pi else -1.0,
            m.min_range,
            m.max_range,
            half_h,
        ]
    )


def _occ3(occluders: F64 | None, n: int) -> F64:
    """Occluders as the kernel's (P, M, 7) array (P = 1: the same for every pose)."""
    if occluders is None:
        return np.zeros((1, 0, len(OCC_COLUMNS)))
    occ = np.ascontiguousarray(occluders, dtype=np.float64)
    if occ.ndim == 2:
        occ = occ[None]
    if occ.ndim != 3 or occ.shape[2] != len(OCC_COLUMNS) or occ.shape[0] not in (1, n):
        raise ValueError(f"occluders must be (M, 7) or (N, M, 7), got {occ.shape}")
    return occ


def _radius(px: F64, py: F64, cx: F64, cy: F64) -> float:
    """Largest horizontal distance of a sample from its pose's centre, m."""
    if px.size == 0:
        return 0.0
    return float(np.sqrt(np.max((px[0] - cx[0]) ** 2 + (py[0] - cy[0]) ** 2)))


def body_per_sensor_pd(
    scene: Scene,
    x: F64,
    y: F64,
    psi: F64,
    sun_dirs: F64 | None = None,
    sensors: Sequence[Sensor] | None = None,
    occluders: F64 | None = None,
    points: BodyPoints | None = None,
) -> tuple[F64, F64]:
    """(S, N) Pd and visible fraction of every sensor (default: the scene's) for N target
    bodies at vehicle-frame centres x, y (m) and relative headings psi (rad), with
    ``occluders`` (see ``body_sensor_pd``; ``None``: none); ``points``: the bodies'
    samples if the caller has them (``body_points`` of the same poses)."""
    x = np.asarray(x, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    px, py, pz, nx, ny = points if points is not None else _scene_points(scene, x, y, psi)
    sens = scene.sensors if sensors is None else sensors
    pd = np.zeros((len(sens), len(x)))
    frac = np.zeros((len(sens), len(x)))
    for row, s in enumerate(sens):
        pd[row], frac[row] = body_sensor_pd(scene, s, x, y, px, py, pz, nx, ny, sun_dirs, occluders)
    return pd, frac


def body_grid(
    scene: Scene,
    grid: GridSpec,
    heading_rad: float,
    per_sensor: bool = False,
    chunk: int = 20_000,
    occluders: F64 | None = None,
) -> GridCoverage:
    """Coverage of target *bodies* centred at the grid's cells at one heading relative to
    the ego (rad): fused Pd per cell (and per sensor), in chunks of ``chunk`` cells, with
    static ``occluders`` ((M, 7), ``coverage.occluders``). The grid's height is not used:
    a body stands on the ground."""
    xs, ys = np.meshgrid(grid.xs(), grid.ys())
    x, y = xs.ravel(), ys.ravel()
    fused = np.zeros(x.size)
    per = np.zeros((len(scene.sensors), x.size)) if per_sensor else None
    for a in range(0, x.size, chunk):
        sl = slice(a, min(a + chunk, x.size))
        pd, _ = body_per_sensor_pd(
            scene, x[sl], y[sl], np.full(sl.stop - sl.start, heading_rad), occluders=occluders
        )
        fused[sl] = -np.expm1(log_miss_of(pd).sum(axis=0))
        if per is not None:
            per[:, sl] = pd
    shape = (grid.ny, grid.nx)
    cov = GridCoverage(grid, fused.reshape(shape) + 0.0, [s.id for s in scene.sensors])
    if per is not None:
        for i, s in enumerate(scene.sensors):
            cov.pd[s.id] = per[i].reshape(shape)
    return cov
