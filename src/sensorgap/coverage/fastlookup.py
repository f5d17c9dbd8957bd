"""Compiled (numba) map lookup along tracks: one pass over the (B, T) target positions of
a batch that interpolates the fused ln(1 - Pd) map, turns each row's sun into the vehicle
frame at every step and finds the steps at which it can glare a camera.

The pass only *finds* what needs more than the map: points outside the map (listed for an
exact evaluation) and (point, camera) pairs with a glare weight > 0 (listed with their
weight); ``logmiss.lookup_log_miss_tracks`` evaluates those. The glare weight is the
``GlareCone`` form of ``Camera.glare_weights`` (tested equal to it), the sun direction the
one of ``Conditions.sun_directions``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.jit import njit

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]
I64 = NDArray[np.int64]

#: Per-row sun encoding (column 0 of the ``sun`` array): no direct sun, a world-frame sun
#: (azimuth clockwise from north, turned by the ego heading), a vehicle-frame sun.
SUN_NONE, SUN_WORLD, SUN_VEHICLE = 0, 1, 2
#: Glare weights at or below this count as none (as in ``Camera.glare_weights``).
GLARE_W_MIN = 1e-9


@njit(nogil=True, inline="always")
def bilerp(
    ax: float, ay: float, a: float, b: float, c: float, d: float
) -> float:  # pragma: no cover - compiled
    """Bilinear interpolation at fractions ``ax``, ``ay`` in [0, 1] of a cell whose corner
    values are ``a`` (i, j), ``b`` (i + 1, j), ``c`` (i, j + 1), ``d`` (i + 1, j + 1): the
    one formula of every compiled map lookup."""
    return (1.0 - ay) * ((1.0 - ax) * a + ax * b) + ay * ((1.0 - ax) * c + ax * d)


@njit(nogil=True, inline="always")
def place(
    x: float, y: float, c: float, s: float, u: float, v: float
) -> tuple[float, float]:  # pragma: no cover - compiled
    """A point (``u``, ``v``) of a target's frame (m) with the target at (``x``, ``y``), m,
    heading cosine ``c`` and sine ``s``: the point's position, m (vehicle frame when the
    pose is; the outline points of ``fastglare.glared_pass``, ``body.place_sample``)."""
    return x + c * u - s * v, y + s * u + c * v


@njit(nogil=True, inline="always")
def map_cell(
    x0: float, y0: float, inv_res: float, nx: int, ny: int, x: float, y: float
) -> tuple[bool, int, int, float, float]:  # pragma: no cover - compiled
    """The cell of an (``ny``, ``nx``) map (``x0``, ``y0``: first cell centre, m;
    ``inv_res``: cells per m) whose four corner cells surround the point (``x``, ``y``),
    m: (on the map, column i, row j, fractions ax, ay in [0, 1] for ``bilerp``); off the
    map (False, 0, 0, 0, 0). The one placement of every compiled map lookup."""
    fx = (x - x0) * inv_res
    fy = (y - y0) * inv_res
    if not (fx >= 0.0 and fy >= 0.0 and fx <= nx - 1 and fy <= ny - 1):
        return False, 0, 0, 0.0, 0.0
    i = min(int(fx), nx - 2)
    j = min(int(fy), ny - 2)
    return True, i, j, fx - i, fy - j


@njit(nogil=True, inline="always")
def corners_in_view(
    img: F32, i: int, j: int
) -> tuple[int, float, float, float, float]:  # pragma: no cover - compiled
    """How many of the four corner cells of a map that is NaN out of view are in view
    (finite, 0 to 4), and their values (j, i), (j, i + 1), (j + 1, i), (j + 1, i + 1) in
    the order of ``bilerp``."""
    a, b, c, d = img[j, i], img[j, i + 1], img[j + 1, i], img[j + 1, i + 1]
    n_in = int(np.isfinite(a)) + int(np.isfinite(b)) + int(np.isfinite(c)) + int(np.isfinite(d))
    return n_in, a, b, c, d


@njit(nogil=True, inline="always")
def bilinear_finite_at(
    img: F32, x0: float, y0: float, inv_res: float, x: float, y: float
) -> tuple[float, int]:  # pragma: no cover - compiled
    """Bilinear value of a map that is NaN out of view at the point (``x``, ``y``), m
    (``x0``, ``y0``: first cell centre, m; ``inv_res``: cells per m), and its state: 1 all
    four corner cells in view (interpolated), 0 none (out of view), 2 some (the edge of
    the field of view) or off the map; the value is 0 unless the state is 1."""
    ny, nx = img.shape
    on_map, i, j, ax, ay = map_cell(x0, y0, inv_res, nx, ny, x, y)
    if not on_map:
        return 0.0, 2
    n_in, a, b, c, d = corners_in_view(img, i, j)
    if n_in == 0:
        return 0.0, 0
    if n_in < 4:
        return 0.0, 2
    return bilerp(ax, ay, a, b, c, d), 1


@njit(nogil=True, inline="always")
def heading_bin(psi: float, inv_bin: float, n_bins: int) -> int:  # pragma: no cover - compiled
    """The bin of a relative heading ``psi`` (rad) among ``n_bins`` over a half turn (a box
    is symmetric under it): ``round(psi / bin width) mod n_bins``, ``inv_bin`` = n_bins /
    pi. (The same bin as ``round((psi mod pi) / bin width) mod n_bins`` but at exact
    rounding ties; the float modulo took 15 % of ``lookup_pass``.)"""
    return int(round(psi * inv_bin)) % n_bins


@njit(nogil=True)
def fade(o: float, margin: float) -> float:  # pragma: no cover - compiled
    """Glare weight at an angle ``o`` (rad) outside the field of view."""
    if o <= 0.0:
        return 1.0
    if o >= margin:
        return 0.0
    w = math.cos(0.5 * math.pi * o / margin) ** 2
    return w if w > GLARE_W_MIN else 0.0


#: 1 / (2 pi), 1/rad.
_INV_TWO_PI = 0.5 / math.pi


@njit(nogil=True)
def _azimuth_off(a: float, yaw: float) -> float:  # pragma: no cover - compiled
    """|a - yaw| wrapped to [0, pi], rad."""
    d = a - yaw
    # (the turn count by a multiplication: it differs from the division only where d + pi
    # is within a rounding of a whole turn, where both wraps give the same angle)
    return abs(d - 2.0 * math.pi * math.floor((d + math.pi) * _INV_TWO_PI))


@njit(nogil=True)
def _cone_weight(
    dx: float,
    dy: float,
    dz: float,
    rot: F64,
    c: int,
    half_h: float,
    half_v: float,
    margin: float,
    cos_bound: float,
) -> float:  # pragma: no cover - compiled
    """Glare weight of a vehicle-frame sun unit vector for cone ``c`` of stacked (C, 3, 3)
    rotations (indexed, not sliced: no array view per call in the hot loop)."""
    xx = dx * rot[c, 0, 0] + dy * rot[c, 1, 0] + dz * rot[c, 2, 0]
    if not xx >= cos_bound:  # certainly farther than the margin from the field of view
        return 0.0
    yy = dx * rot[c, 0, 1] + dy * rot[c, 1, 1] + dz * rot[c, 2, 1]
    zz = dx * rot[c, 0, 2] + dy * rot[c, 1, 2] + dz * rot[c, 2, 2]
    az = math.atan2(yy, xx)
    el = math.atan2(zz, math.hypot(xx, yy))
    return fade(math.hypot(max(0.0, abs(az) - half_h), max(0.0, abs(el) - half_v)), margin)


@njit(nogil=True)
def _level_weight(
    a: float, el: float, yaw: float, half_h: float, half_v: float, margin: float
) -> float:  # pragma: no cover - compiled
    """Glare weight for a level camera (pitch 0): the sun's sensor azimuth is its
    vehicle-frame azimuth ``a`` minus ``yaw``, its elevation ``el`` (rad)."""
    eh = max(0.0, _azimuth_off(a, yaw) - half_h)
    ev = max(0.0, el - half_v)
    return fade(eh if ev == 0.0 else (ev if eh == 0.0 else math.hypot(eh, ev)), margin)


@njit(nogil=True)
def glare_cone_weight(
    dx: float,
    dy: float,
    dz: float,
    rot: F64,
    half_h: float,
    half_v: float,
    margin: float,
    cos_bound: float,
) -> float:  # pragma: no cover - compiled
    """Glare weight of one vehicle-frame sun unit vector for one ``GlareCone`` (3x3
    ``rot``)."""
    return _cone_weight(dx, dy, dz, rot.reshape(1, 3, 3), 0, half_h, half_v, margin, cos_bound)


def cone_cos_bound(half_h: float, half_v: float, margin: float) -> float:
    """Cheap bound: a direction whose cosine to the boresight is below this lies farther
    than ``margin`` from the field of view (as in ``geometry.angles_outside_fov``)."""
    a = min(half_h + margin, math.pi)
    b = min(half_v + margin, 0.5 * math.pi)
    return math.cos(a) * math.cos(b) if a < 0.5 * math.pi else -2.0


@njit(nogil=True)
def lookup_pass(
    total: F32,
    x0: float,
    y0: float,
    inv_res: float,
    x: F64,
    y: F64,
    heading: F64,
    psi: F64,
    n: I64,
    rows: I64,
    sun: F64,
    rot: F64,
    half_h: F64,
    half_v: F64,
    margin: F64,
    cos_bound: F64,
    yaw: F64,
    level: NDArray[np.bool_],
    mount_xy: F64,
    reach2: F64,
    signal: F32,
    has_signal: NDArray[np.bool_],
    keep_unseen: bool,
    near_view: NDArray[np.bool_],
    also_total: F32,
    also_at: NDArray[np.bool_],
    also_out: F64,
    out: F64,
    outside: I64,
    glare_idx: I64,
    glare_w: F64,
    glare_state: NDArray[np.int8],
    counts: I64,
) -> None:  # pragma: no cover - compiled
    """For each row r in ``rows`` and step k < n[r] of (B, T) vehicle-frame positions (m):
    ``out[r, k]`` = bilinear ``total[h]`` (``total``: (H, ny, nx) maps, one per bin of the
    target's heading relative to the ego over a half turn, ``h = round(psi mod pi / (pi /
    H)) mod H`` with ``psi[r, k]`` in rad; 0 outside the map); outside points go to
    ``outside`` (flat index r * T + k, count in ``counts[0]``); for each camera c with a
    glare weight w > 0 at an inside point that it may see, (flat index, w, state) go to
    ``glare_idx[c]``, ``glare_w[c]``, ``glare_state[c]`` (count in ``counts[1 + c]``);
    state 1: all four corner cells of its ``signal`` map (received signal, NaN out of
    view) are in view, 2: some are, or it has no signal map (``has_signal``); points with
    none in view are skipped unless ``keep_unseen`` and one of their corner cells is
    ``near_view`` ((C, ny, nx): some cell within a target body's reach of it is in view,
    ``near_view_mask``; ``reach2`` then includes that reach), first by the squared
    horizontal distance to the camera (``mount_xy``) against ``reach2``: (max range + a
    cell diagonal)^2, beyond which no corner cell can be in range. ``sun[r]`` = (kind,
    azimuth rad, elevation rad); ``heading`` (B, T) ego heading, rad. Level cameras
    (``level``, pitch 0) get their weight analytically (sensor azimuth a - ``yaw``,
    elevation the sun's), others through ``rot``. ``also_total`` ((H, ny, nx), or (0, ny,
    nx) for none): fused maps of further sensors, none of them glare-prone, interpolated
    alike into ``also_out[r, k]`` ((B, T)) at the steps where ``also_at[r, k]`` (a reaction
    model's moving-only sensors where the target moves; left as they are elsewhere and
    outside the map), in the same pass."""
    n_bins, ny, nx = total.shape[0], total.shape[1], total.shape[2]
    also = also_total.shape[0] > 0
    inv_bin = n_bins / math.pi
    t = x.shape[1]
    n_cam = rot.shape[0]
    # per camera and row: 0 never glared, 1 a constant weight wc, 2 a weight per step
    mode = np.zeros(n_cam, dtype=np.int8)
    wc = np.zeros(n_cam)
    for q in range(rows.size):
        r = rows[q]
        kind = int(sun[r, 0])
        el = sun[r, 2]
        cel = math.cos(el)
        sel = math.sin(el)
        n_active = 0
        if kind != SUN_NONE:
            # Row-level culling: turning the ego by d rad moves the sun direction by at
            # most d rad, so a camera whose boresight is farther than its bound plus the
            # largest turn from step 0 at step 0 is never glared in this row; without a
            # turn the weight is the same at every step.
            turn = 0.0
            if kind == SUN_WORLD:
                for k in range(n[r]):
                    turn = max(turn, abs(heading[r, k] - heading[r, 0]))
                a0 = 0.5 * math.pi - sun[r, 1] - heading[r, 0]
            else:
                a0 = sun[r, 1]
            dx0 = cel * math.cos(a0)
            dy0 = cel * math.sin(a0)
            for c in range(n_cam):
                mode[c] = 2
                if cos_bound[c] > -1.0:
                    bx = dx0 * rot[c, 0, 0] + dy0 * rot[c, 1, 0] + sel * rot[c, 2, 0]
                    ang = math.acos(min(1.0, max(-1.0, bx)))
                    if ang - turn > math.acos(cos_bound[c]) + 1e-9:
                        mode[c] = 0
                if mode[c] != 0 and level[c]:
                    # exact for a level camera: its sun azimuth is a - yaw, which moves by
                    # at most `turn`; its sun elevation is the sun's
                    d0 = _azimuth_off(a0, yaw[c])
                    if el - half_v[c] >= margin[c] or d0 - turn - half_h[c] >= margin[c]:
                        mode[c] = 0
                    elif d0 + turn <= half_h[c] and el <= half_v[c]:
                        mode[c] = 1  # inside the field of view at every step
                        wc[c] = 1.0
                if mode[c] == 2 and turn == 0.0:
                    mode[c] = 1
                    if level[c]:
                        wc[c] = _level_weight(a0, el, yaw[c], half_h[c], half_v[c], margin[c])
                    else:
                        wc[c] = _cone_weight(
                            dx0, dy0, sel, rot, c, half_h[c], half_v[c], margin[c], cos_bound[c]
                        )
                if mode[c] == 1 and not wc[c] > 0.0:
                    mode[c] = 0
                n_active += int(mode[c] != 0)
        for k in range(n[r]):
            on_map, i, j, ax, ay = map_cell(x0, y0, inv_res, nx, ny, x[r, k], y[r, k])
            if not on_map:
                out[r, k] = 0.0
                outside[counts[0]] = r * t + k
                counts[0] += 1
                continue
            h = 0
            if n_bins > 1:
                h = heading_bin(psi[r, k], inv_bin, n_bins)
            tot = total[h]
            out[r, k] = bilerp(ax, ay, tot[j, i], tot[j, i + 1], tot[j + 1, i], tot[j + 1, i + 1])
            if also and also_at[r, k]:
                tot = also_total[h]
                also_out[r, k] = bilerp(
                    ax, ay, tot[j, i], tot[j, i + 1], tot[j + 1, i], tot[j + 1, i + 1]
                )
            if n_active == 0:
                continue
            a = sun[r, 1]  # vehicle-frame azimuth of the sun, rad
            if kind == SUN_WORLD:
                a = 0.5 * math.pi - a - heading[r, k]
            have_d = False
            dx = 0.0
            dy = 0.0
            for c in range(n_cam):
                if mode[c] == 0:
                    continue
                if mode[c] == 1:
                    w = wc[c]
                elif level[c]:
                    w = _level_weight(a, el, yaw[c], half_h[c], half_v[c], margin[c])
                else:
                    if not have_d:
                        dx = cel * math.cos(a)
                        dy = cel * math.sin(a)
                        have_d = True
                    w = _cone_weight(
                        dx, dy, sel, rot, c, half_h[c], half_v[c], margin[c], cos_bound[c]
                    )
                if not w > 0.0:
                    continue
                st = 2
                if has_signal[c]:  # which corner cells the camera sees
                    ox = x[r, k] - mount_xy[c, 0]
                    oy = y[r, k] - mount_xy[c, 1]
                    if ox * ox + oy * oy > reach2[c]:  # every corner cell beyond its range
                        continue
                    n_in = corners_in_view(signal[c], i, j)[0]
                    if n_in == 0:
                        if not keep_unseen:
                            continue  # out of its view: Pd = 0 with or without glare
                        # a body around the point: is its view within the body's reach?
                        nv = near_view[c]
                        if not (nv[j, i] or nv[j, i + 1] or nv[j + 1, i] or nv[j + 1, i + 1]):
                            continue
                    st = 1 if n_in == 4 else 2
                m = counts[1 + c]
                glare_idx[c, m] = r * t + k
                glare_w[c, m] = w
                glare_state[c, m] = st
                counts[1 + c] = m + 1


@njit(nogil=True)
def body_layer_pass(
    values: F32,
    j0: int,
    i0: int,
    ny: int,
    nx: int,
    x0: float,
    y0: float,
    inv_res: float,
    xs: F64,
    ys: F64,
    psi: F64,
    out: F64,
) -> None:  # pragma: no cover - compiled
    """One sensor's part of the body maps (``LogMissMaps.body_layer``: ``values`` (H, cy,
    cx) on the crop of an (``ny``, ``nx``) map from row ``j0``, column ``i0``, 0 outside
    it) at M target centres, interpolated as ``lookup_pass`` interpolates the totals: the
    heading bin of ``psi`` (rad), the four cells around the centre (``x0``, ``y0``: first
    cell centre, m; ``inv_res``: cells per m) clamped to the map, bilinear."""
    n_bins, cy, cx = values.shape
    inv_bin = n_bins / math.pi
    c = np.empty(4)
    for m in range(xs.size):
        fx = (xs[m] - x0) * inv_res
        fy = (ys[m] - y0) * inv_res
        i = min(max(int(math.floor(fx)), 0), nx - 2)
        j = min(max(int(math.floor(fy)), 0), ny - 2)
        h = 0
        if n_bins > 1:
            h = heading_bin(psi[m], inv_bin, n_bins)
        for corner in range(4):
            jj = j + corner // 2 - j0
            ii = i + corner % 2 - i0
            c[corner] = values[h, jj, ii] if 0 <= jj < cy and 0 <= ii < cx else 0.0
        out[m] = bilerp(fx - i, fy - j, c[0], c[1], c[2], c[3])


def near_view_mask(signal: F32, reach_cells: int) -> NDArray[np.bool_]:
    """(C, ny, nx): whether some cell within ``reach_cells`` (a square of that half side,
    in cells) of each cell has a finite ``signal`` (is in the camera's view): the cells a
    target body centred there may reach into the view from (box dilation by an integral
    image)."""
    c, ny, nx = signal.shape
    k = max(int(reach_cells), 0)
    fin = np.isfinite(signal).astype(np.int32)
    ii = np.zeros((c, ny + 1, nx + 1), dtype=np.int64)
    ii[:, 1:, 1:] = fin.cumsum(axis=1).cumsum(axis=2)
    j0 = np.clip(np.arange(ny) - k, 0, ny)
    j1 = np.clip(np.arange(ny) + k + 1, 0, ny)
    i0 = np.clip(np.arange(nx) - k, 0, nx)
    i1 = np.clip(np.arange(nx) + k + 1, 0, nx)
    box = ii[:, j1][:, :, i1] - ii[:, j0][:, :, i1] - ii[:, j1][:, :, i0] + ii[:, j0][:, :, i0]
    return np.asarray(box > 0)


@njit(nogil=True)
def _sun_directions(
    sun: F64, heading: F64, flat: I64, t: int, out: F64
) -> None:  # pragma: no cover - compiled
    """``out[m]``: the vehicle-frame sun unit vector at flat track index ``flat[m]`` (row
    ``flat // t``; ``sun`` (B, 3) rows (kind, azimuth rad, elevation rad), ``heading``
    flat ego headings, rad); NaN without a direct sun."""
    for m in range(flat.size):
        r = flat[m] // t
        kind = sun[r, 0]
        if kind == SUN_NONE:
            out[m, 0] = np.nan
            out[m, 1] = np.nan
            out[m, 2] = np.nan
            continue
        a = sun[r, 1]
        if kind == SUN_WORLD:
            a = 0.5 * math.pi - a - heading[flat[m]]
        ce = math.cos(sun[r, 2])
        out[m, 0] = ce * math.cos(a)
        out[m, 1] = ce * math.sin(a)
        out[m, 2] = math.sin(sun[r, 2])


def sun_directions_at(sun: F64, heading: F64, flat: I64, t: int) -> F64:
    """(M, 3) vehicle-frame sun unit vectors (NaN rows: no direct sun) at flat indices of
    (B, T) tracks: row ``flat // t`` of the per-row ``sun`` (kind, azimuth rad, elevation
    rad), the flat ego ``heading`` (rad) at ``flat``."""
    out = np.empty((len(flat), 3))
    _sun_directions(
        np.ascontiguousarray(sun, dtype=np.float64),
        np.ascontiguousarray(heading, dtype=np.float64).reshape(-1),
        np.ascontiguousarray(flat, dtype=np.int64),
        int(t),
        out,
    )
    return out


def sun_directions_of(sun: F64, heading: F64) -> F64:
    """(N, 3) vehicle-frame sun unit vectors (NaN rows: no direct sun) of N points with
    per-point ``sun`` (kind, azimuth rad, elevation rad) rows and ego headings (rad)."""
    return sun_directions_at(sun, heading, np.arange(len(sun)), 1)
