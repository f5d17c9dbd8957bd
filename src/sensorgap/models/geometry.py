"""Sensor frames, field-of-view tests and the gain pattern over the field of view.

Vehicle frame: ISO 8855 / OpenSCENARIO (x forward, y left, z up, origin on the ground below
the rear-axle centre). A sensor frame is the vehicle frame translated to the mount and
rotated by yaw (about z, counter-clockwise) then pitch (about the new y; positive pitch
tilts the boresight down). Azimuth is counter-clockwise from the boresight, elevation up
from the sensor's x-y plane.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgap.jit import njit

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class Mount:
    """Pose and field of view of one mounted sensor, SI units (m, rad).

    Attributes:
        x, y, z: position in the vehicle frame, m.
        yaw: rad, (-pi, pi]. pitch: rad, positive = down.
        hfov, vfov: full horizontal / vertical field of view, rad (hfov up to 2 pi).
        min_range, max_range: detection range limits, m (Pd = 0 outside, paper Sec. III).
    """

    x: float
    y: float
    z: float
    yaw: float
    pitch: float
    hfov: float
    vfov: float
    min_range: float
    max_range: float

    def rotation(self) -> NDArray[np.float64]:
        """3x3 matrix whose columns are the sensor axes in the vehicle frame."""
        cy, sy = math.cos(self.yaw), math.sin(self.yaw)
        cp, sp = math.cos(self.pitch), math.sin(self.pitch)
        rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
        ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
        return rz @ ry


def heading_rad(heading_deg: float) -> float:
    """A heading in degrees as radians in [0, 2 pi): equal angles (360 and 0, -90 and 270)
    give the same value to the last bit, so they evaluate alike (a target pose that touches
    the ego's body flipped with the sign of sin(2 pi) = -2.4e-16)."""
    return math.radians(heading_deg % 360.0)


def rotate_offsets(mount: Mount, dx: F64, dy: F64, dz: F64 | float) -> tuple[F64, F64, F64]:
    """Offsets from the mount (vehicle-frame axes, m) -> sensor-frame coordinates (m)."""
    cy, sy = math.cos(mount.yaw), math.sin(mount.yaw)
    u = cy * dx + sy * dy
    v = -sy * dx + cy * dy
    w = np.broadcast_to(np.asarray(dz, dtype=np.float64), u.shape)
    if mount.pitch == 0.0:
        return u, v, w
    cp, sp = math.cos(mount.pitch), math.sin(mount.pitch)
    return cp * u - sp * w, v, sp * u + cp * w


def spherical(xs: F64, ys: F64, zs: F64) -> tuple[F64, F64, F64]:
    """Sensor-frame Cartesian (m) -> range (m), azimuth (rad, (-pi, pi]), elevation (rad)."""
    rho2 = xs * xs + ys * ys
    r = np.sqrt(rho2 + zs * zs)
    az = np.arctan2(ys, xs)
    el = np.arctan2(zs, np.sqrt(rho2))
    return r, az, el


def sensor_range(xs: F64, ys: F64, zs: F64) -> F64:
    """Range (m) of sensor-frame points."""
    return np.asarray(np.sqrt(xs * xs + ys * ys + zs * zs), dtype=np.float64)


def fov_mask(mount: Mount, xs: F64, ys: F64, zs: F64) -> NDArray[np.bool_]:
    """True where a sensor-frame point (m) is inside the angular field of view.

    Equivalent to ``|az| <= hfov/2 and |el| <= vfov/2`` but without trigonometry:
    ``|y| <= x tan(hfov/2)`` (hfov < 180 deg), ``x >= 0`` (hfov = 180 deg), outside the
    rear cone ``x < 0, |y| < -x tan(pi - hfov/2)`` (180..360 deg), and
    ``z^2 <= (x^2 + y^2) tan^2(vfov/2)``.
    """
    half_h = 0.5 * mount.hfov
    half_v = 0.5 * mount.vfov
    if half_h >= math.pi:
        ok = np.ones(xs.shape, dtype=bool)
    elif half_h == 0.5 * math.pi:
        ok = xs >= 0.0
    elif half_h < 0.5 * math.pi:
        ok = (xs > 0.0) & (np.abs(ys) <= xs * math.tan(half_h))
    else:
        ok = ~((xs < 0.0) & (np.abs(ys) < -xs * math.tan(math.pi - half_h)))
    if half_v < 0.5 * math.pi:
        t2 = math.tan(half_v) ** 2
        ok &= zs * zs <= (xs * xs + ys * ys) * t2
    return ok


def in_range(mount: Mount, r: F64) -> NDArray[np.bool_]:
    """True where 0 < r, min_range <= r <= max_range (r in m).

    A point at r = 0 (the aperture itself) is never in view: the minimum range is the
    sensor's blind zone where detection is defined as 0, not computed.
    """
    ok = (r > 0.0) & (r <= mount.max_range)
    if mount.min_range > 0.0:
        ok &= r >= mount.min_range
    return ok


def pattern_loss_db(az: F64, el: F64, hfov: float, vfov: float, edge_loss_db: float) -> F64:
    """One-way gain loss over the field of view, dB (>= 0).

    Parabolic (Gaussian-beam) pattern in dB, separable in azimuth and elevation:
    ``L = edge_loss_db * ((2 az / hfov)^2 + (2 el / vfov)^2)``, so the loss is
    ``edge_loss_db`` at each field-of-view edge (3 dB when the field of view is the 3-dB
    beamwidth, the usual data-sheet definition; ITU-R F.1336-style main lobe). A zero-width
    field of view contributes no loss (only its boresight is in view).
    """
    if edge_loss_db == 0.0:
        return np.zeros_like(az)
    loss = np.zeros_like(az)
    if hfov > 0.0:
        loss += (2.0 * az / hfov) ** 2
    if vfov > 0.0:
        loss += (2.0 * el / vfov) ** 2
    return edge_loss_db * loss


def direction_angles(mount: Mount, direction: tuple[float, float, float]) -> tuple[float, float]:
    """Azimuth and elevation (rad) of a vehicle-frame unit direction in the sensor frame."""
    d = mount.rotation().T @ np.asarray(direction, dtype=np.float64)
    az = math.atan2(float(d[1]), float(d[0]))
    el = math.atan2(float(d[2]), math.hypot(float(d[0]), float(d[1])))
    return az, el


def angle_outside_fov(mount: Mount, direction: tuple[float, float, float]) -> float:
    """How far (rad) a direction lies outside the field of view; 0 inside it."""
    az, el = direction_angles(mount, direction)
    ex_h = max(0.0, abs(az) - 0.5 * mount.hfov)
    ex_v = max(0.0, abs(el) - 0.5 * mount.vfov)
    return math.hypot(ex_h, ex_v)


def angles_outside_fov(mount: Mount, directions: F64, limit: float = math.inf) -> F64:
    """Vectorised ``angle_outside_fov``: (N, 3) vehicle-frame unit directions -> how far
    (rad) each lies outside the field of view (0 inside; NaN rows give inf). With a finite
    ``limit`` (rad), directions certainly farther than that from the field of view may be
    reported as inf without computing the angles (a cheap bound on the boresight angle)."""
    d = np.ascontiguousarray(directions, dtype=np.float64)
    out = np.empty(len(d))
    a = min(0.5 * mount.hfov + limit, math.pi)
    b = min(0.5 * mount.vfov + limit, 0.5 * math.pi)
    cos_bound = math.cos(a) * math.cos(b) if a < 0.5 * math.pi else -2.0
    _outside_kernel(
        d,
        np.ascontiguousarray(mount.rotation()),
        0.5 * mount.hfov,
        0.5 * mount.vfov,
        cos_bound,
        out,
    )
    return out


@njit(nogil=True)
def _outside_kernel(
    d: F64, rot: F64, half_h: float, half_v: float, cos_bound: float, out: F64
) -> None:  # pragma: no cover - compiled
    for k in range(d.shape[0]):
        x = d[k, 0] * rot[0, 0] + d[k, 1] * rot[1, 0] + d[k, 2] * rot[2, 0]
        if not x >= cos_bound:  # NaN (no sun) or certainly beyond the limit
            out[k] = np.inf
            continue
        y = d[k, 0] * rot[0, 1] + d[k, 1] * rot[1, 1] + d[k, 2] * rot[2, 1]
        z = d[k, 0] * rot[0, 2] + d[k, 1] * rot[1, 2] + d[k, 2] * rot[2, 2]
        az = math.atan2(y, x)
        el = math.atan2(z, math.hypot(x, y))
        ex_h = max(0.0, abs(az) - half_h)
        ex_v = max(0.0, abs(el) - half_v)
        out[k] = math.hypot(ex_h, ex_v)


def horizontal_reach_bbox(mount: Mount, height: float) -> tuple[float, float, float, float] | None:
    """Conservative (xmin, xmax, ymin, ymax) in the vehicle frame, m, of the points at
    ``height`` that the sensor can possibly see; ``None`` when it can see none.

    Uses the horizontal sector of radius ``sqrt(max_range^2 - dz^2)`` around the mount
    between yaw +- hfov/2 (widened by the pitch-induced azimuth skew, conservatively to the
    full circle when pitched).
    """
    dz = height - mount.z
    if abs(dz) > mount.max_range:
        return None
    rh = math.sqrt(max(mount.max_range**2 - dz * dz, 0.0))
    half = 0.5 * mount.hfov
    if half >= math.pi or mount.pitch != 0.0:
        return (mount.x - rh, mount.x + rh, mount.y - rh, mount.y + rh)
    a0, a1 = mount.yaw - half, mount.yaw + half
    angles = [a0, a1]
    k = math.ceil(a0 / (0.5 * math.pi))
    while k * 0.5 * math.pi <= a1:
        angles.append(k * 0.5 * math.pi)
        k += 1
    xs = [mount.x] + [mount.x + rh * math.cos(a) for a in angles]
    ys = [mount.y] + [mount.y + rh * math.sin(a) for a in angles]
    return (min(xs), max(xs), min(ys), max(ys))


def separation_cos(dx: F64, dy: F64, dz: F64 | float, directions: F64) -> F64:
    """Cosine of the angle between offsets from a mount (vehicle-frame axes, m; the line
    of sight to a point) and (N, 3) vehicle-frame unit ``directions`` (e.g. to the sun).
    NaN rows (no direction) and zero offsets give -1 (as far apart as possible)."""
    dz_a = np.broadcast_to(np.asarray(dz, dtype=np.float64), np.shape(dx))
    r = np.sqrt(dx * dx + dy * dy + dz_a * dz_a)
    d = np.asarray(directions, dtype=np.float64)
    dot = dx * d[:, 0] + dy * d[:, 1] + dz_a * d[:, 2]
    c = np.divide(dot, r, out=np.full(np.shape(dx), -1.0), where=r > 0.0)
    return np.asarray(np.clip(np.nan_to_num(c, nan=-1.0), -1.0, 1.0), dtype=np.float64)
