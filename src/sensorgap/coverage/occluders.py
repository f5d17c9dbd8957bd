"""Occlusion by other road users and objects: boxes standing on the ground that hide parts
of a target's body from a sensor (issue #17).

An occluder is a box (``length_m`` x ``width_m`` x ``height_m``, from the ground up) centred
at a vehicle-frame position with a heading relative to the ego, e.g. a truck in the next
lane or a parked car. A target body's outline sample is hidden from a sensor when the
straight segment from the sensor's mount to the sample passes through any occluder (a slab
test in the occluder's own frame, 3D: a 4 m truck hides a car behind it, a 1.5 m parked
car hides a 1.1 m child but not the upper samples of a 1.8 m adult). Hidden samples are not
visible, so the visible fraction and the SNR of the visible part of the target-body model
(``coverage.body``) fall: adding an occluder never raises a sensor's Pd (every quantity the
detection rule uses is monotone in the visible set). ``None`` or an empty set of occluders
is the paper's setting (an empty road).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgap.config.common import finite_real, name_problem, shown
from sensorgap.config.target import (
    MAX_HEIGHT_M,
    MAX_LENGTH_M,
    MAX_WIDTH_M,
    MIN_SIZE_M,
    TargetConfig,
)
from sensorgap.errors import InputError
from sensorgap.jit import njit

F64 = NDArray[np.float64]

#: Columns of an occluder array: centre x, y (m, vehicle frame), cos and sin of the heading
#: relative to the ego, half length, half width, height (m).
COLUMNS = ("x", "y", "cos", "sin", "half_length", "half_width", "height")

#: Farthest occluder centre from the ego, m, in x and in y (``Occluder``; ``coverage
#: --occluder``; docs/limits.md).
MAX_OCCLUDER_M = 1000.0
#: Largest occluder heading, rad, either way (a full turn: ``--occluder`` takes +-360 deg).
MAX_OCCLUDER_HEADING_RAD = 2.0 * math.pi


@dataclass(frozen=True)
class Occluder:
    """A box on the ground: centre ``x``, ``y`` (m, vehicle frame), ``heading`` (rad,
    relative to the ego), ``length``, ``width``, ``height`` (m) and a label (e.g. the target
    class it was sized from)."""

    x: float
    y: float
    heading: float
    length: float
    width: float
    height: float
    label: str = "occluder"

    def __post_init__(self) -> None:
        """Refuse a box no road user could be (``InputError`` naming the field): every
        number finite, the centre within ``MAX_OCCLUDER_M`` of the ego in x and y, the
        heading within +-``MAX_OCCLUDER_HEADING_RAD``, the sizes within the bounds of a
        target class's (``config.target``), the label a name. A NaN centre made every
        sample ray test miss its slab test the wrong way: the whole map came out Pd 0."""
        bounds = {
            "x": (-MAX_OCCLUDER_M, MAX_OCCLUDER_M, "m (vehicle frame)"),
            "y": (-MAX_OCCLUDER_M, MAX_OCCLUDER_M, "m (vehicle frame)"),
            "heading": (-MAX_OCCLUDER_HEADING_RAD, MAX_OCCLUDER_HEADING_RAD, "rad"),
            "length": (MIN_SIZE_M, MAX_LENGTH_M, "m"),
            "width": (MIN_SIZE_M, MAX_WIDTH_M, "m"),
            "height": (MIN_SIZE_M, MAX_HEIGHT_M, "m"),
        }
        for name, (lo, hi, unit) in bounds.items():
            v = getattr(self, name)
            number = finite_real(v)
            if number is None or not lo <= number <= hi:
                raise InputError(
                    "Occluder",
                    name,
                    f"must be a finite number within {lo:g}..{hi:g} {unit}, got {shown(v)}",
                )
            object.__setattr__(self, name, number)  # numpy scalars as plain floats
        why = name_problem(self.label) if isinstance(self.label, str) else "must be a string"
        if why:
            raise InputError("Occluder", "label", f"{why}, got {shown(self.label)}")

    @classmethod
    def of_target(cls, target: TargetConfig, x: float, y: float, heading_rad: float) -> Occluder:
        """An occluder the size of a target class from targets.toml (its box)."""
        return cls(
            x,
            y,
            heading_rad,
            float(target.length_m),
            float(target.width_m),
            float(target.height_m),
            target.name,
        )

    def row(self) -> F64:
        """This occluder as one row of ``COLUMNS``."""
        return np.array(
            [
                self.x,
                self.y,
                math.cos(self.heading),
                math.sin(self.heading),
                0.5 * self.length,
                0.5 * self.width,
                self.height,
            ]
        )

    def corners(self) -> F64:
        """(4, 2) footprint corners, vehicle frame, m (counter-clockwise)."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        hl, hw = 0.5 * self.length, 0.5 * self.width
        local = np.array([[hl, hw], [-hl, hw], [-hl, -hw], [hl, -hw]])
        return np.column_stack(
            [self.x + c * local[:, 0] - s * local[:, 1], self.y + s * local[:, 0] + c * local[:, 1]]
        )

    def overlaps(self, footprint: Sequence[tuple[float, float]]) -> bool:
        """Whether this box's footprint and a convex ``footprint`` (corners in order, m,
        vehicle frame; e.g. the ego body's, ``BodyConfig.footprint``) share interior
        area (separating-axis test on both polygons' edge normals; boxes that only touch
        along an edge or at a corner do not overlap)."""
        a = self.corners()
        b = np.asarray(footprint, dtype=np.float64)
        for poly in (a, b):
            edges = np.roll(poly, -1, axis=0) - poly
            for nx, ny in np.column_stack([-edges[:, 1], edges[:, 0]]):
                pa, pb = a @ (nx, ny), b @ (nx, ny)
                tol = 1e-9 * max(1.0, float(np.hypot(nx, ny)))
                if pa.max() <= pb.min() + tol or pb.max() <= pa.min() + tol:
                    return False  # a separating axis
        return True


def occluder_array(occluders: Sequence[Occluder] | None) -> F64:
    """(M, 7) array of ``COLUMNS`` (M = 0 without occluders)."""
    if not occluders:
        return np.zeros((0, len(COLUMNS)))
    return np.asarray(np.vstack([o.row() for o in occluders]), dtype=np.float64)


@njit(nogil=True)
def hidden_by_boxes(
    ox: float, oy: float, oz: float, px: float, py: float, pz: float, boxes: F64
) -> bool:  # pragma: no cover - compiled
    """True when the segment from ``o`` (a sensor's mount) to ``p`` (a target sample), m,
    passes through any box of ``boxes`` (rows of ``COLUMNS``; slab test in each box's
    frame, z from 0 to its height)."""
    for b in range(boxes.shape[0]):
        cx, cy, c, s = boxes[b, 0], boxes[b, 1], boxes[b, 2], boxes[b, 3]
        hl, hw, h = boxes[b, 4], boxes[b, 5], boxes[b, 6]
        ax = c * (ox - cx) + s * (oy - cy)
        ay = -s * (ox - cx) + c * (oy - cy)
        bx = c * (px - cx) + s * (py - cy)
        by = -s * (px - cx) + c * (py - cy)
        o = (ax, ay, oz)
        d = (bx - ax, by - ay, pz - oz)
        lo = (-hl, -hw, 0.0)
        hi = (hl, hw, h)
        t0, t1 = 0.0, 1.0
        miss = False
        for a in range(3):
            if d[a] == 0.0:
                if o[a] <= lo[a] or o[a] >= hi[a]:
                    miss = True
                    break
                continue
            ta = (lo[a] - o[a]) / d[a]
            tb = (hi[a] - o[a]) / d[a]
            t0 = max(t0, min(ta, tb))
            t1 = min(t1, max(ta, tb))
        if not miss and t0 < t1:
            return True
    return False


def ego_frame_boxes(ex: F64, ey: F64, eh: F64, ox: F64, oy: F64, oh: F64, sizes: F64) -> F64:
    """Occluder boxes in the ego's vehicle frame at every step: ego rear-axle states ``ex``,
    ``ey`` (m), ``eh`` (rad), each (B, T); occluder centre states ``ox``, ``oy``, ``oh``,
    each (M, B, T); ``sizes`` (M, 3) length, width, height (m). Returns (B, T, M, 7) rows
    of ``COLUMNS``."""
    m = ox.shape[0]
    out = np.empty(ex.shape + (m, len(COLUMNS)))
    c, s = np.cos(eh), np.sin(eh)
    for j in range(m):
        dx, dy = ox[j] - ex, oy[j] - ey
        rel = oh[j] - eh
        out[..., j, 0] = c * dx + s * dy
        out[..., j, 1] = -s * dx + c * dy
        out[..., j, 2] = np.cos(rel)
        out[..., j, 3] = np.sin(rel)
        out[..., j, 4] = 0.5 * sizes[j, 0]
        out[..., j, 5] = 0.5 * sizes[j, 1]
        out[..., j, 6] = sizes[j, 2]
    return out


def may_hide(
    boxes: F64, x: F64, y: F64, target_radius: float, mount_radius: float
) -> NDArray[np.bool_]:
    """(N,) whether any of the (N, M, 7) boxes may hide part of a target body centred at
    ``x``, ``y`` (m, vehicle frame; ``target_radius``: its footprint's half diagonal, m)
    from a sensor mounted within ``mount_radius`` (m) of the origin: a box whose footprint
    circle comes within ``max(target_radius, mount_radius)`` of the segment origin ->
    target centre. Conservative: a point ``(1 - u) m + u p`` of a ray from a mount ``m`` to a
    sample ``p`` lies within ``(1 - u) |m| + u |p - c| <= max(...)`` of the point ``u c``
    of that segment, so a box the ray passes through is never missed."""
    bx, by = boxes[..., 0], boxes[..., 1]
    r_box = np.hypot(boxes[..., 4], boxes[..., 5])
    px, py = x[:, None], y[:, None]
    ll = np.maximum(px * px + py * py, 1e-12)
    u = np.clip((bx * px + by * py) / ll, 0.0, 1.0)
    d = np.hypot(bx - u * px, by - u * py)
    return np.asarray(np.any(d <= r_box + max(target_radius, mount_radius), axis=-1))


def shadow_polygon(occ: Occluder, mount_xy: tuple[float, float], reach_m: float) -> F64:
    """(K, 2) ground-plane shadow of an occluder's footprint seen from a mount at
    ``mount_xy`` (m), extended to ``reach_m`` from the mount: the region behind the box
    hidden at any height *not above the occluder's height* (for a plot and hand checks; the
    model tests rays in 3D). Counter-clockwise: the two silhouette corners, then their
    projections."""
    cs = occ.corners()
    mx, my = mount_xy
    ang = np.arctan2(cs[:, 1] - my, cs[:, 0] - mx)
    ref = ang[0]
    rel = np.angle(np.exp(1j * (ang - ref)))
    i_lo, i_hi = int(np.argmin(rel)), int(np.argmax(rel))
    a, b = cs[i_lo], cs[i_hi]

    def far(p: F64) -> F64:
        d = p - np.array([mx, my])
        return np.array([mx, my]) + d / max(float(np.hypot(*d)), 1e-12) * reach_m

    return np.asarray(np.vstack([a, b, far(b), far(a)]), dtype=np.float64)


__all__ = [
    "COLUMNS",
    "Occluder",
    "ego_frame_boxes",
    "hidden_by_boxes",
    "may_hide",
    "occluder_array",
    "shadow_polygon",
]
