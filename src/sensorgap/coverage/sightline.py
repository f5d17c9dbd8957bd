"""Line of sight to a target body past other road users: what *perfect perception* can see.

The collision outcome compares the vehicle with a reference that has perfect perception
(docs/models.md, "Collision outcome"). Perfect perception cannot see through a lorry: the
reference perceives the target at a step when some outline sample of its body facing a
viewpoint has a free line of sight from that viewpoint past every occluder box
(``occluders.hidden_by_boxes``). Viewpoints: the mounts of the sensors that confirm targets
for braking, and a driver's eye point (UN R157's careful and competent driver is the
reference of the ALKS regulation). The target counts as perceived at a step when, from some
viewpoint, at least ``REFERENCE_MIN_VISIBLE_FRACTION`` of the body's outline samples facing
that viewpoint are in sight (the camera's recognition rule). Field of view, range, weather
and the ego's own body are ignored: perfect sensors, only the line of sight counts. Without
occluders every step is seen (the previous reference: confirmed at step M - 1).

Driver's eye point, in the vehicle frame (x forward from the rear axle, y left, z up), m:
an ESTIMATE for a left-hand-drive passenger car: x = 0.55 wheelbase (the driver sits a
little ahead of the wheelbase's middle), y = +0.37 (seat centreline left of the car's), z =
min(1.2, height - 0.2) (sedan eye heights are about 1.1-1.2 m: the ocular points of UN R125
lie 0.635 m above the seat reference point, itself about 0.5 m above the road).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.config.target import TargetConfig
from sensorgap.config.vehicle import BodyConfig
from sensorgap.coverage.body import body_samples, facing_offset, place_sample
from sensorgap.coverage.occluders import hidden_by_boxes
from sensorgap.jit import njit

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: Driver's eye point (module docstring): x as a fraction of the wheelbase, y, m, and the
#: eye height, m, at most ``height - EYE_BELOW_ROOF_M`` (all estimates).
EYE_X_WHEELBASE = 0.55
EYE_Y_M = 0.37
EYE_Z_M = 1.2
EYE_BELOW_ROOF_M = 0.2
#: Perfect perception recognises a target when at least this fraction of its outline
#: samples facing a viewpoint are in sight from it: the camera's rule (``body``: image
#: detectors lose most of their recall once about half of an object is hidden; Dollar et
#: al., IEEE TPAMI 2012). An ESTIMATE of recognising a road user, as a driver must before
#: braking for it: a sliver of a car beside a lead car is not enough.
REFERENCE_MIN_VISIBLE_FRACTION = 0.5


def driver_eye(body: BodyConfig) -> tuple[float, float, float]:
    """The driver's eye point of a vehicle body in its frame, m (an estimate, above)."""
    return (
        EYE_X_WHEELBASE * body.wheelbase_m,
        EYE_Y_M,
        min(EYE_Z_M, body.height_m - EYE_BELOW_ROOF_M),
    )


def viewpoints(body: BodyConfig) -> F64:
    """(1, 3) viewpoints of perfect perception, m: the driver's eye (module docstring). The
    reference depends on the vehicle's body, never on its sensors, so two sensor sets on
    one body are judged against the same reference."""
    return np.array([driver_eye(body)], dtype=np.float64)


@njit(nogil=True)
def _seen(
    x: float,
    y: float,
    psi: float,
    bx: F64,
    by: F64,
    bz: F64,
    bnx: F64,
    bny: F64,
    views: F64,
    boxes: F64,
    frac: float,
) -> bool:  # pragma: no cover - compiled
    """Whether, from some viewpoint, at least ``frac`` of the body's outline samples facing
    it (at x, y, psi) have a free line of sight past ``boxes``."""
    if boxes.shape[0] == 0:
        return True
    c, s = math.cos(psi), math.sin(psi)
    k = bx.shape[0]
    px = np.empty(k)
    py = np.empty(k)
    nx = np.empty(k)
    ny = np.empty(k)
    for j in range(k):
        px[j], py[j], nx[j], ny[j] = place_sample(x, y, c, s, bx[j], by[j], bnx[j], bny[j])
    for v in range(views.shape[0]):
        vx, vy, vz = views[v, 0], views[v, 1], views[v, 2]
        facing = 0
        for j in range(k):
            if facing_offset(nx[j], ny[j], px[j], py[j], vx, vy) > 0.0:
                facing += 1
        if facing == 0:
            continue
        need = max(1, int(math.ceil(frac * facing - 1e-9)))
        seen = 0
        left = facing
        for j in range(k):
            if facing_offset(nx[j], ny[j], px[j], py[j], vx, vy) <= 0.0:
                continue  # the sample's face looks away from this viewpoint
            left -= 1
            if not hidden_by_boxes(vx, vy, vz, px[j], py[j], bz[j], boxes):
                seen += 1
                if seen >= need:
                    return True
            if seen + left < need:
                break
    return False


@njit(nogil=True)
def _first_seen_kernel(
    x: F64,
    y: F64,
    psi: F64,
    n_valid: I64,
    rows: I64,
    occ: F64,
    bx: F64,
    by: F64,
    bz: F64,
    bnx: F64,
    bny: F64,
    views: F64,
    m: int,
    n: int,
    frac: float,
    out: I64,
) -> None:  # pragma: no cover - compiled
    mask = (1 << n) - 1
    for r in rows:
        bits = 0
        out[r] = -1
        for k in range(n_valid[r]):
            hit = _seen(x[r, k], y[r, k], psi[r, k], bx, by, bz, bnx, bny, views, occ[r, k], frac)
            bits = ((bits << 1) | (1 if hit else 0)) & mask
            count = 0
            b = bits
            while b:
                count += b & 1
                b >>= 1
            if count >= m:
                out[r] = k
                break


def perfect_confirmation_step(
    x: F64,
    y: F64,
    psi: F64,
    n_valid: I64,
    occluders: F64,
    target: TargetConfig,
    views: F64,
    confirm_m: int,
    confirm_n: int,
    rows: I64,
) -> I64:
    """(B,) the step at which perfect perception confirms the target (M of the last N
    steps seen, module docstring): target centres ``x``, ``y`` (m) and headings ``psi``
    (rad) in the ego frame, (B, T); ``occluders`` (B, T, M, 7) ego-frame boxes
    (``occluders.COLUMNS``); only the first ``n_valid`` steps count; -1 when never. Rows
    not in ``rows`` get ``confirm_m - 1`` (seen at every step)."""
    b = x.shape[0]
    out = np.full(b, confirm_m - 1, dtype=np.int64)
    if rows.size == 0:
        return out
    body = body_samples(target)
    _first_seen_kernel(
        np.ascontiguousarray(x),
        np.ascontiguousarray(y),
        np.ascontiguousarray(psi),
        np.ascontiguousarray(n_valid, np.int64),
        np.ascontiguousarray(rows, np.int64),
        np.ascontiguousarray(occluders),
        body.x,
        body.y,
        body.z,
        body.nx,
        body.ny,
        np.ascontiguousarray(views),
        int(confirm_m),
        int(confirm_n),
        REFERENCE_MIN_VISIBLE_FRACTION,
        out,
    )
    return out
