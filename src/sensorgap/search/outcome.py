"""Criticality in collision terms: would the vehicle under test, with its sensors and its
reaction model, confirm the target in time to brake and avoid the collision?

Pure numpy + numba (no I/O). Two stages over a batch of B candidates on one time axis (T
steps of ``dt`` s); units: m, s, rad, m/s, m/s2, m/s3.

1. **Encounter geometry** (``encounter_geometry``, sensor-independent). The ego drives its
   planned path (rear-axle samples ``x, y, heading``) at its planned speed ``v0`` (open
   loop; ``ego.speed[:, 0]`` is used: the families keep it constant, to within ~1 % where a
   lane offset meets a curve), so its progress (arc length) along the path is
   ``p_k = v0 t_k``. Its body is the box
   ``[x_rear, x_front] x [-width/2, width/2]`` about the rear axle. For every step j the
   target's box (centre, heading, length, width) is put into the frame of the nearest ego
   path sample i (path-aligned ``u``, lateral ``v``) and clipped to the ego's lane band
   ``|v| <= width/2``: the ego, moved along the path to rear-axle progress q, overlaps it
   exactly when ``q`` is in ``[lo_j, hi_j] = [s_i + u_min - x_front, s_i + u_max - x_rear]``
   (``u_min, u_max``: the u extent of the clipped box; an exact box-overlap test on
   straight paths). On curved paths (largest curvature kappa of the row) one straight
   frame errs laterally by up to ``delta = kappa (span + v0 dt)^2 / 2`` (span: the ego's
   reach plus the target's half diagonal): a target surely inside the band (by delta) has
   each end of its interval recomputed in the frame of the path sample at that end (the
   ego's own pose there); one within delta of the band's edge is judged progress by
   progress, each in the frame of its own path sample. What remains is the ego's pose
   between samples taken along the sample's tangent: cm-level, tested against a direct
   separating-axis simulation of the ego's interpolated poses (R >= 50 m: agreement except
   grazing contacts within 5 cm). The open-loop collision is the first step j with ``p_j`` in
   ``[lo_j, hi_j]``; the *path TTC* at step k is ``t_j - t_k`` (0 from the collision on, inf
   without one). The *threat onset* ``k_threat`` is the first step at which the target's
   box, widened by ``threat_margin_m`` on each side perpendicular to the ego's path
   (equivalently, the ego's lane band widened by the margin), overlaps the ego's boxes along
   its planned path over the next ``threat_horizon_s`` (rear-axle progress
   ``[p_k, p_k + v0 H]``), with its lateral offset from the path predicted over the next
   ``threat_prediction_s`` at its current lateral rate (a causal difference of the last two
   steps; the predicted offset closest to the path counts, the box's heading and
   longitudinal position kept): a target that is moving towards the ego's path (a
   pedestrian walking out, a car starting a lane change) is a threat up to that long
   before it reaches the widened band, while one moving along or away from the path is
   judged where it is (0 s: no prediction).

2. **Reaction** (``reaction_outcome``). The target is *confirmed* at the first step at
   which at least M of the last N sensor cycles detected it (fewer cycles at the start: M
   of those available), with per-step probability ``pd_confirm`` of the confirming sensor
   types (independent cycles) over the first ``n_valid`` steps. The distribution of that
   first step, ``f[k]`` (k < T) and ``f[T]`` = P(never), is exact: a Markov chain over the
   last N - 1 detection bits (``first_confirmation``; the reachable states, those with
   fewer than M detections; only sums of non-negative terms, rows sum to 1 to rounding).
   Confirmation at step k starts braking at ``t_b = max(t_k, t_threat) + latency_s``: the
   deceleration ramps up with jerk J (``jerk_m_s3``) to ``A = min(decel_max, mu g)`` and
   holds to standstill (speed never below 0); the ego stays on its planned path, only its
   progress drops by the lost distance ``L(tau) = v0 tau - d(tau)``, ``d`` the closed-form
   jerk-limited braking distance ``tau`` s after onset. Confirmation at k collides
   (``c_k = 1``) if some step j has braked progress ``p_j - L(t_j - t_b)`` in ``[lo_j,
   hi_j]`` (the target's planned states on the whole time axis, also after ``n_valid``).
   Per step j the colliding onsets form one interval (L is monotone), found by a monotone
   search (a walk from the last step's answer, else bisection); each onset keeps its first
   colliding step (path-compressed fill), so all onsets of a candidate cost O(T log T).
   An onset that has not met the target by the last step is not avoided yet: with the
   target still in the ego's path there, the encounter continues past the time axis
   (``after_horizon``: target at its last speed along the path, ego braking on) for as
   long as the target stays in the path at its speed across it (``Encounter.exit_s``).
   Without confirmation the vehicle does not brake: ``c_never`` is the open-loop outcome.

Outputs (``Outcome``, (B,) arrays): ``collision_probability = sum_k f_k c_k + f_T c_never``
(exact, no monotonicity in k assumed); ``impact_speed_kmh``: expected magnitude of the
relative velocity (braked ego speed along its heading minus the target's velocity) at the
first overlap, given a collision (0 without); ``collision_perfect`` (and its impact speed):
``c`` for perfect perception (Pd = 1 every step: confirmed at step M - 1) with the same
reaction; ``t_safe_s``: the latest ``t_k`` such that confirmation at every step <= k avoids
the collision (NaN when confirmation at step 0 collides; the last step's time when nothing
collides); ``t_confirm_median_s``: the first ``t_k`` with cumulative ``f >= 1/2``;
``detection_margin_s = t_safe_s - t_confirm_median_s``; ``t_threat_s``;
``p_never_confirmed = f_T``.

Conventions of this project (deliberate): an encounter without an open-loop collision has
nothing to avoid, so its collision probability is 0 (braking for a near miss, which could
turn it into a rear-end or crossing collision, is the planner's choice, not a sensor's
failure); the same holds for a target that never becomes a threat and for an ego slower
than ``MIN_EGO_SPEED_M_S`` (braking cannot change the outcome: the open-loop one counts).
The confirmation distribution and its summaries (``t_confirm_median_s``,
``detection_margin_s``, ``p_never_confirmed``) are computed only where there is a collision
to avoid (NaN elsewhere), which is also what keeps this stage fast. The path TTC is
``Encounter.ttc_path`` (B, T).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgap.jit import njit
from sensorgap.search.fastkin import cos_sin_near

if TYPE_CHECKING:
    from sensorgap.config.reaction import ReactionConfig
    from sensorgap.scenarios.batch import Tracks

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: Standard gravity, m/s2.
G_M_S2 = 9.80665
#: Below this planned ego speed braking cannot change the encounter, m/s.
MIN_EGO_SPEED_M_S = 0.1
#: Longest confirmation window (the chain has up to 2^(N-1) states).
MAX_CONFIRM_N = 16


@dataclass(frozen=True)
class Encounter:
    """Encounter geometry of B candidates on T steps (see the module docstring).

    Attributes:
        lo, hi: (B, T) ego rear-axle progress along its path, m, at which the ego would
            overlap the target at step j (NaN where the target is not in the ego's lane
            band at step j).
        v0: (B,) planned ego speed, m/s (``progress``: the planned progress
            ``p_k = v0 t_k``, m, (B, T)).
        collide_step: (B,) first open-loop overlap step (-1: none).
        threat_step: (B,) threat onset step (-1: never a threat).
        ttc_path: (B, T) time to the open-loop collision along the paths, s (inf: none;
            0 from the collision on).
        ego_heading, target_heading: (B, T) planned headings, rad; target_speed: (B, T),
            m/s (the impact speed needs them). dt: step, s.
        exit_s: (B,) at the last step, how long the target would stay in the ego's lane
            band at its lateral speed across the path, s (0: not in it; inf: not moving
            across it; None: not computed); the collision outcome continues an encounter
            past the time axis only for that long (``after_horizon``).
    """

    lo: F64
    hi: F64
    v0: F64
    collide_step: I64
    threat_step: I64
    ttc_path: F64
    ego_heading: F64
    target_heading: F64
    target_speed: F64
    dt: float
    exit_s: F64 | None = None

    @property
    def progress(self) -> F64:
        """(B, T) planned ego progress along its path ``p_k = v0 t_k``, m."""
        return np.asarray(
            self.v0[:, None] * (self.dt * np.arange(self.lo.shape[1]))[None, :], dtype=np.float64
        )


# --------------------------------------------------------------------------- geometry


@njit(nogil=True)
def _edge_band(
    ua: float, va: float, ub: float, vb: float, band: float, umin: float, umax: float
) -> tuple[float, float]:  # pragma: no cover - compiled
    """Widen (umin, umax) by the points where edge a-b crosses the lines v = +-band."""
    if (va - band) * (vb - band) < 0.0:
        u = ua + (band - va) / (vb - va) * (ub - ua)
        umin = min(umin, u)
        umax = max(umax, u)
    if (va + band) * (vb + band) < 0.0:
        u = ua + (-band - va) / (vb - va) * (ub - ua)
        umin = min(umin, u)
        umax = max(umax, u)
    return umin, umax


@njit(nogil=True)
def _band_u_range(
    uc: float, vc: float, cd: float, sd: float, hl: float, hw: float, band: float
) -> tuple[float, float]:  # pragma: no cover - compiled
    """u extent, m, of a box (centre ``uc, vc``; axis ``cd, sd`` = cos/sin of its heading
    in this frame; half length ``hl``, half width ``hw``) clipped to ``|v| <= band``;
    ``umin > umax`` when the box misses the band. Exact for a convex polygon: the extremes
    lie on its corners inside the band or where its edges cross the band's lines."""
    u0 = uc + cd * hl - sd * hw
    v0 = vc + sd * hl + cd * hw
    u1 = uc + cd * hl + sd * hw
    v1 = vc + sd * hl - cd * hw
    u2 = uc - cd * hl + sd * hw
    v2 = vc - sd * hl - cd * hw
    u3 = uc - cd * hl - sd * hw
    v3 = vc - sd * hl + cd * hw
    vmin = min(min(v0, v1), min(v2, v3))
    vmax = max(max(v0, v1), max(v2, v3))
    if vmin > band or vmax < -band:
        return np.inf, -np.inf
    if vmin >= -band and vmax <= band:
        return min(min(u0, u1), min(u2, u3)), max(max(u0, u1), max(u2, u3))
    umin, umax = np.inf, -np.inf
    if -band <= v0 <= band:
        umin, umax = min(umin, u0), max(umax, u0)
    if -band <= v1 <= band:
        umin, umax = min(umin, u1), max(umax, u1)
    if -band <= v2 <= band:
        umin, umax = min(umin, u2), max(umax, u2)
    if -band <= v3 <= band:
        umin, umax = min(umin, u3), max(umax, u3)
    umin, umax = _edge_band(u0, v0, u1, v1, band, umin, umax)
    umin, umax = _edge_band(u1, v1, u2, v2, band, umin, umax)
    umin, umax = _edge_band(u2, v2, u3, v3, band, umin, umax)
    umin, umax = _edge_band(u3, v3, u0, v0, band, umin, umax)
    return umin, umax


@njit(nogil=True)
def _frame_range(
    exi: float,
    eyi: float,
    c: float,
    s: float,
    px: float,
    py: float,
    ct: float,
    st: float,
    hl: float,
    hw: float,
    band: float,
) -> tuple[float, float]:  # pragma: no cover - compiled
    """The u extent of the target box (centre ``px, py``; heading cos/sin ``ct, st``) clipped
    to the band, in the frame of the ego path sample at ``exi, eyi`` with heading cos/sin
    ``c, s``."""
    dx = px - exi
    dy = py - eyi
    return _band_u_range(
        c * dx + s * dy, -s * dx + c * dy, ct * c + st * s, st * c - ct * s, hl, hw, band
    )


@njit(nogil=True)
def _scan_interval(
    ex: F64,
    ey: F64,
    eh: F64,
    r: int,
    ia: int,
    ib: int,
    step: float,
    px: float,
    py: float,
    ct: float,
    st: float,
    hl: float,
    hw: float,
    x_front: float,
    x_rear: float,
    half_w: float,
    ec: F64,
    es: F64,
    done: NDArray[np.bool_],
) -> tuple[float, float]:  # pragma: no cover
    """The overlap interval of rear-axle progress on a curved path: every progress q is
    judged in the frame of its own path sample (the cell ``s_i +- step/2``), samples ia..ib;
    ``lo > hi`` when none overlaps."""
    t = eh.shape[1]
    lo = np.inf
    hi = -np.inf
    for i in range(ia, ib + 1):
        if not done[i]:
            ec[i] = math.cos(eh[r, i])
            es[i] = math.sin(eh[r, i])
            done[i] = True
        u1, u2 = _frame_range(ex[r, i], ey[r, i], ec[i], es[i], px, py, ct, st, hl, hw, half_w)
        if u1 > u2:
            continue
        s_i = step * i
        a = s_i + u1 - x_front
        z = s_i + u2 - x_rear
        if i > 0:
            a = max(a, s_i - 0.5 * step)
        if i < t - 1:
            z = min(z, s_i + 0.5 * step)
        if a <= z:
            lo = min(lo, a)
            hi = max(hi, z)
    return lo, hi


@njit(nogil=True, inline="always")
def _nearest_sample(
    ex: F64, ey: F64, r: int, i: int, px: float, py: float
) -> int:  # pragma: no cover - compiled
    """The ego path sample of row ``r`` nearest the point (``px``, ``py``), m: a hill-climb
    from sample ``i`` (``_nearest_guess``'s, or the last answer at the end of a row)."""
    t = ex.shape[1]
    best = (ex[r, i] - px) ** 2 + (ey[r, i] - py) ** 2
    while i + 1 < t:
        d = (ex[r, i + 1] - px) ** 2 + (ey[r, i + 1] - py) ** 2
        if d >= best:
            break
        best = d
        i += 1
    while i > 0:
        d = (ex[r, i - 1] - px) ** 2 + (ey[r, i - 1] - py) ** 2
        if d >= best:
            break
        best = d
        i -= 1
    return i


@njit(nogil=True, inline="always")
def _d2(ex: F64, ey: F64, r: int, i: int, px: float, py: float) -> float:  # pragma: no cover
    """Squared distance, m2, of ego path sample ``i`` of row ``r`` to (``px``, ``py``)."""
    dx = ex[r, i] - px
    dy = ey[r, i] - py
    return dx * dx + dy * dy


@njit(nogil=True)
def _nearest_guess(
    ex: F64,
    ey: F64,
    tx: F64,
    ty: F64,
    xr: F64,
    r: int,
    inv_step: float,
    near: I64,
    more: NDArray[np.bool_],
) -> None:  # pragma: no cover - compiled
    """Per step j of row ``r``: the ego path sample nearest the target centre, from the
    target's distance ahead of the ego at step j (``xr``, m, ego frame; ``inv_step``: path
    samples per m) moved by one sample to a smaller distance if there is one (``near``),
    and whether the next sample along that way is nearer still (``more``: then
    ``_nearest_sample`` climbs on, in about 1 step in 15 on the benchmark). Steps do not
    depend on each other (no branch on the data, no value carried over), so this loop
    overlaps steps where a hill-climb from the last answer waited for it (11 % of the
    geometry kernel on the benchmark, same results)."""
    t = ex.shape[1]
    for j in range(t):
        px = tx[r, j]
        py = ty[r, j]
        g = min(max(j + int(math.floor(xr[r, j] * inv_step + 0.5)), 0), t - 1)
        ga = max(g - 1, 0)
        gb = min(g + 1, t - 1)
        da = _d2(ex, ey, r, ga, px, py)
        dc = _d2(ex, ey, r, g, px, py)
        db = _d2(ex, ey, r, gb, px, py)
        fwd = db < dc
        back = (da < dc) & (db >= dc)
        way = int(fwd) - int(back)
        k = g + way
        best = min(dc, db) if fwd else min(dc, da)
        kn = min(max(k + way, 0), t - 1)
        near[j] = k
        more[j] = (way != 0) & (_d2(ex, ey, r, kn, px, py) < best)


@njit(nogil=True)
def _geometry_kernel(
    ex: F64,
    ey: F64,
    eh: F64,
    v0: F64,
    tx: F64,
    ty: F64,
    th: F64,
    tv: F64,
    xr: F64,
    hl: float,
    hw: float,
    x_front: float,
    x_rear: float,
    half_w: float,
    margin: float,
    horizon: float,
    predict: float,
    dt: float,
    lo: F64,
    hi: F64,
    collide: I64,
    threat: I64,
    ttc: F64,
    exit_out: F64,
) -> None:  # pragma: no cover
    b, t = ex.shape
    inv_dt = 1.0 / dt  # (a multiplication per step instead of a division)
    ec = np.empty(t)
    es = np.empty(t)
    done = np.empty(t, dtype=np.bool_)
    near = np.zeros(t, dtype=np.int64)
    more = np.zeros(t, dtype=np.bool_)
    # beyond this lateral offset of its centre the target box cannot reach the widened band
    reach = half_w + margin + math.sqrt(hl * hl + hw * hw)
    # how far along the path from the sample nearest the target the ego's box can touch it
    span = max(x_front, -x_rear) + math.sqrt(hl * hl + hw * hw)
    for r in range(b):
        collide[r] = -1
        threat[r] = -1
        step = v0[r] * dt
        if step > 0.0:
            _nearest_guess(ex, ey, tx, ty, xr, r, 1.0 / step, near, more)
        else:  # a standing ego: every sample is the same point
            near[:] = 0
            more[:] = False
        turn = 0.0  # largest heading change between path samples, rad
        for k in range(t):
            done[k] = False
            if k > 0 and step > 0.0:
                d = abs(eh[r, k] - eh[r, k - 1])
                if d > 0.0:
                    if d > math.pi:
                        d = abs(d - 2.0 * math.pi * math.floor(d / (2.0 * math.pi) + 0.5))
                    turn = max(turn, d)
        # largest path curvature of the row, 1/m (one division: the same as the largest
        # of the per-sample quotients, division by a positive number being monotone)
        kappa = turn / step if step > 0.0 else 0.0
        # lateral error of a single straight frame over the span (0 on straight paths)
        delta = 0.5 * kappa * (span + step) ** 2
        lh = np.nan  # the last ego heading whose cos/sin were computed, and those
        lc = 1.0
        ls = 0.0
        th_last = np.nan
        ct = 1.0
        st = 0.0
        i = 0
        # the last exactly computed step (a target standing still repeats it)
        cpx = np.nan
        cpy = np.nan
        cth = np.nan
        ca = np.nan
        cz = np.nan
        cw1 = np.inf
        cw2 = -np.inf
        cs = 0.0
        cvc = np.nan  # the cached step's lateral offset and lateral rate
        cvd = 0.0
        pvc = np.nan  # the previous step's lateral offset from the path, m
        for j in range(t):
            px = tx[r, j]
            py = ty[r, j]
            a = np.nan  # the overlap interval of rear-axle progress at step j
            z = np.nan
            w1 = np.inf  # the target's u extent in the widened band (threat), frame i
            w2 = -np.inf
            s_i = 0.0
            # the lateral rate is known once a previous step is (a causal difference)
            vdot = 0.0
            if predict > 0.0 and px == cpx and py == cpy and th[r, j] == cth and pvc == pvc:
                vdot = (cvc - pvc) * inv_dt
            if px == cpx and py == cpy and th[r, j] == cth and vdot == cvd:
                a, z, w1, w2, s_i = ca, cz, cw1, cw2, cs
                pvc = cvc
            else:
                exact = True
                # nearest ego path sample to the target centre (``_nearest_guess``)
                i = near[j]
                if more[j]:
                    i = _nearest_sample(ex, ey, r, i, px, py)
                if not done[i]:  # cos/sin of the ego heading, once per sample
                    if eh[r, i] != lh:
                        lc, ls = cos_sin_near(eh[r, i], lh, lc, ls)
                        lh = eh[r, i]
                    ec[i] = lc
                    es[i] = ls
                    done[i] = True
                c = ec[i]
                s = es[i]
                dx = px - ex[r, i]
                dy = py - ey[r, i]
                vc = -s * dx + c * dy
                # predicted lateral offset closest to the path over the prediction horizon
                # (constant lateral rate relative to the path; = vc without prediction)
                vp = vc
                if predict > 0.0:
                    vdot = 0.0 if pvc != pvc else (vc - pvc) * inv_dt
                    v1 = vc + vdot * predict
                    if vc * v1 <= 0.0:
                        vp = 0.0
                    elif abs(v1) < abs(vc):
                        vp = v1
                pvc = vc
                if abs(vc) <= reach + delta or abs(vp) <= reach + delta:
                    if th[r, j] != th_last:
                        ct, st = cos_sin_near(th[r, j], th_last, ct, st)
                        th_last = th[r, j]
                    cd = ct * c + st * s
                    sd = st * c - ct * s
                    ext_u = abs(cd) * hl + abs(sd) * hw  # the box's half extents here
                    ext_v = abs(sd) * hl + abs(cd) * hw
                    if threat[r] < 0 and abs(vp) - ext_v <= half_w + margin + delta:
                        s_i = step * i
                        w1, w2 = _band_u_range(c * dx + s * dy, vp, cd, sd, hl, hw, half_w + margin)
                    if abs(vc) - ext_v <= half_w + margin + delta:
                        uc = c * dx + s * dy
                        s_i = step * i
                        if delta == 0.0:  # straight: one frame is exact
                            u1, u2 = _band_u_range(uc, vc, cd, sd, hl, hw, half_w)
                            if u1 <= u2:
                                a = s_i + u1 - x_front
                                z = s_i + u2 - x_rear
                        elif (
                            s_i
                            + uc
                            - ext_u
                            - x_front
                            - kappa * (span + step) * (abs(uc) + abs(vc) + hl + hw)
                            - delta
                            > step * j
                        ):
                            # the ego's reach at step j is still short of the target in
                            # any frame: the straight frame's interval will do for now
                            exact = False
                            u1, u2 = _band_u_range(uc, vc, cd, sd, hl, hw, half_w)
                            if u1 <= u2:
                                a = s_i + u1 - x_front
                                z = s_i + u2 - x_rear
                        else:
                            # surely in the band: each end of the interval in the frame of
                            # the ego's own pose there
                            sure = False
                            if half_w > delta:
                                u1, u2 = _band_u_range(uc, vc, cd, sd, hl, hw, half_w - delta)
                                if u1 <= u2:
                                    u1, u2 = _band_u_range(uc, vc, cd, sd, hl, hw, half_w)
                                    il = min(
                                        max(int(math.floor((s_i + u1 - x_front) / step + 0.5)), 0),
                                        t - 1,
                                    )
                                    ih = min(
                                        max(int(math.floor((s_i + u2 - x_rear) / step + 0.5)), 0),
                                        t - 1,
                                    )
                                    for ii in (il, ih):
                                        if not done[ii]:
                                            if eh[r, ii] != lh:
                                                lc, ls = cos_sin_near(eh[r, ii], lh, lc, ls)
                                                lh = eh[r, ii]
                                            ec[ii] = lc
                                            es[ii] = ls
                                            done[ii] = True
                                    a1, a2 = _frame_range(
                                        ex[r, il],
                                        ey[r, il],
                                        ec[il],
                                        es[il],
                                        px,
                                        py,
                                        ct,
                                        st,
                                        hl,
                                        hw,
                                        half_w,
                                    )
                                    z1, z2 = _frame_range(
                                        ex[r, ih],
                                        ey[r, ih],
                                        ec[ih],
                                        es[ih],
                                        px,
                                        py,
                                        ct,
                                        st,
                                        hl,
                                        hw,
                                        half_w,
                                    )
                                    if a1 <= a2 and z1 <= z2:
                                        a = step * il + a1 - x_front
                                        z = step * ih + z2 - x_rear
                                        sure = True
                            if not sure:
                                # near the band's edge: every progress in its own frame
                                u1, u2 = _band_u_range(uc, vc, cd, sd, hl, hw, half_w + delta)
                                if u1 <= u2:
                                    ia = min(
                                        max(
                                            int(math.floor((s_i + u1 - x_front - delta) / step))
                                            - 1,
                                            0,
                                        ),
                                        t - 1,
                                    )
                                    ib = min(
                                        max(
                                            int(math.ceil((s_i + u2 - x_rear + delta) / step)) + 1,
                                            0,
                                        ),
                                        t - 1,
                                    )
                                    u1, u2 = _scan_interval(
                                        ex,
                                        ey,
                                        eh,
                                        r,
                                        ia,
                                        ib,
                                        step,
                                        px,
                                        py,
                                        ct,
                                        st,
                                        hl,
                                        hw,
                                        x_front,
                                        x_rear,
                                        half_w,
                                        ec,
                                        es,
                                        done,
                                    )
                                    if u1 <= u2:
                                        a = u1
                                        z = u2
                if exact:
                    cpx, cpy, cth = px, py, th[r, j]
                    ca, cz, cw1, cw2, cs = a, z, w1, w2, s_i
                    cvc, cvd = vc, vdot
            lo[r, j] = a
            hi[r, j] = z
            pj = step * j
            if collide[r] < 0 and a <= pj <= z:
                collide[r] = j
            if (
                threat[r] < 0
                and w1 <= w2
                and s_i + w2 >= pj + x_rear
                and s_i + w1 <= pj + x_front + v0[r] * horizon
            ):
                threat[r] = j
        kc = collide[r]
        if kc >= 0 and (threat[r] < 0 or threat[r] > kc):
            threat[r] = kc  # an overlap is always a threat
        for k in range(t):
            ttc[r, k] = np.inf if kc < 0 else max(kc - k, 0) * dt
        # at the last step: how long the target stays in the lane band at its speed across
        # the path (in the frame of the path sample nearest it)
        e = t - 1
        ie = _nearest_sample(ex, ey, r, i, tx[r, e], ty[r, e])
        ce = math.cos(eh[r, ie])
        se = math.sin(eh[r, ie])
        vcl = -se * (tx[r, e] - ex[r, ie]) + ce * (ty[r, e] - ey[r, ie])
        dh = th[r, e] - eh[r, ie]
        lim = half_w + abs(math.sin(dh)) * hl + abs(math.cos(dh)) * hw
        vd = tv[r, e] * math.sin(dh)  # its speed across the path, m/s (to the left > 0)
        if abs(vcl) > lim:
            exit_out[r] = 0.0
        elif abs(vd) < 1e-9:
            exit_out[r] = np.inf
        elif vd > 0.0:
            exit_out[r] = (lim - vcl) / vd
        else:
            exit_out[r] = (vcl + lim) / -vd


def encounter_geometry(
    ego: Tracks,
    target: Tracks,
    dt: float,
    target_size: tuple[float, float],
    ego_body: tuple[float, float, float],
    threat_margin_m: float,
    threat_horizon_s: float,
    threat_prediction_s: float = 0.0,
    ego_frame_x: ArrayLike | None = None,
) -> Encounter:
    """Encounter geometry of (B, T) world-frame planned states (``scenarios.batch.Tracks``):
    ``ego``, the ego rear axle (x, y in m, heading in rad, speed in m/s; the speed is taken
    as constant, ``ego.speed[:, 0]``) and ``target``, the target box centre (same units), on
    a time axis of step ``dt`` s.

    ``target_size`` = (length, width), m; ``ego_body`` = (x_front, x_rear, width), m, the
    bumpers relative to the rear axle (``x_rear < 0 < x_front``); ``threat_margin_m``, m,
    and ``threat_horizon_s``, s, define the threat onset, ``threat_prediction_s``, s, its
    lateral prediction (0: none; module docstring). ``ego_frame_x``: (B, T) the target
    centre's distance ahead of the ego rear axle along the ego heading, m, if known
    (``search.fastkin``; computed here otherwise): where the search for the nearest path
    sample starts."""
    ex = np.ascontiguousarray(ego.x, dtype=np.float64)
    if ex.ndim != 2 or ex.shape[1] < 2:
        raise ValueError(f"expected (B, T >= 2) states, got shape {ex.shape}")
    b, t = ex.shape
    x_front, x_rear, width = (float(v) for v in ego_body)
    length, t_width = (float(v) for v in target_size)
    if not (x_rear < 0.0 < x_front and width > 0.0 and length > 0.0 and t_width > 0.0):
        raise ValueError("need x_rear < 0 < x_front and positive widths and target length")
    if not (
        dt > 0.0
        and threat_margin_m >= 0.0
        and threat_horizon_s >= 0.0
        and threat_prediction_s >= 0.0
    ):
        raise ValueError("need dt > 0 and non-negative threat margin, horizon and prediction")
    arrays = [
        np.ascontiguousarray(a, dtype=np.float64)
        for a in (ego.y, ego.heading, target.x, target.y, target.heading, target.speed)
    ]
    ey, eh, tx, ty, th, tv = arrays
    if any(a.shape != (b, t) for a in arrays):
        raise ValueError("all state arrays must have the same (B, T) shape")
    v0 = np.ascontiguousarray(np.asarray(ego.speed, dtype=np.float64).reshape(b, t)[:, 0])
    if ego_frame_x is None:
        xr = np.ascontiguousarray((tx - ex) * np.cos(eh) + (ty - ey) * np.sin(eh))
    else:
        xr = np.ascontiguousarray(ego_frame_x, dtype=np.float64)
        if xr.shape != (b, t):
            raise ValueError("ego_frame_x must have the (B, T) shape of the states")
    lo, hi, ttc = (np.empty((b, t)) for _ in range(3))
    collide = np.empty(b, dtype=np.int64)
    threat = np.empty(b, dtype=np.int64)
    exit_s = np.empty(b)
    _geometry_kernel(
        ex,
        ey,
        eh,
        v0,
        tx,
        ty,
        th,
        tv,
        xr,
        0.5 * length,
        0.5 * t_width,
        x_front,
        x_rear,
        0.5 * width,
        float(threat_margin_m),
        float(threat_horizon_s),
        float(threat_prediction_s),
        float(dt),
        lo,
        hi,
        collide,
        threat,
        ttc,
        exit_s,
    )
    return Encounter(lo, hi, v0, collide, threat, ttc, eh, th, tv, float(dt), exit_s)


# ----------------------------------------------------------------------- confirmation


@lru_cache(maxsize=64)
def _chain_tables(m: int, n: int) -> tuple[I64, I64, I64]:
    """Transitions of the M-of-N chain over the reachable states (the last N - 1 bits with
    fewer than M detections, state 0 first): next state after a miss, after a detection
    (-1: confirmed)."""
    mask_s = (1 << (n - 1)) - 1
    mask_n = (1 << n) - 1
    states = [s for s in range(mask_s + 1) if bin(s).count("1") < m]
    index = {s: i for i, s in enumerate(states)}
    miss = np.array([index[(s << 1) & mask_s] for s in states], dtype=np.int64)
    hit = np.array(
        [
            -1 if bin(((s << 1) | 1) & mask_n).count("1") >= m else index[((s << 1) | 1) & mask_s]
            for s in states
        ],
        dtype=np.int64,
    )
    return np.array(states, dtype=np.int64), miss, hit


@njit(nogil=True)
def _first_confirmation_kernel(
    pd: F64, n_valid: I64, rows: I64, miss: I64, hit: I64, out: F64
) -> None:  # pragma: no cover - compiled
    """``out[r, k]`` = P(first confirmation at step k), ``out[r, T]`` = P(none within the
    first ``n_valid[r]`` steps), for the given rows (others untouched)."""
    t = pd.shape[1]
    ns = miss.shape[0]
    prob = np.empty(ns)
    nxt = np.empty(ns)
    for r in rows:
        for s in range(ns):
            prob[s] = 0.0
        prob[0] = 1.0
        for k in range(t + 1):
            out[r, k] = 0.0
        for k in range(min(max(n_valid[r], 0), t)):
            p = min(max(pd[r, k], 0.0), 1.0)
            q = 1.0 - p
            for s in range(ns):
                nxt[s] = 0.0
            f = 0.0
            for s in range(ns):
                w = prob[s]
                if w == 0.0:
                    continue
                h = hit[s]
                if h < 0:
                    f += w * p
                else:
                    nxt[h] += w * p
                nxt[miss[s]] += w * q
            out[r, k] = f
            for s in range(ns):
                prob[s] = nxt[s]
        rest = 0.0
        for s in range(ns):
            rest += prob[s]
        out[r, t] = rest


def first_confirmation(pd: ArrayLike, n_valid: ArrayLike, m: int, n: int) -> F64:
    """(B, T + 1) distribution of the first M-of-N confirmation step for (B, T) per-step
    detection probabilities (independent cycles; only the first ``n_valid`` steps count;
    fewer than N cycles at the start: M of those available): column k < T is P(first
    confirmation at step k), column T is P(never confirmed). Rows sum to 1 (to rounding)."""
    if not 1 <= m <= n <= MAX_CONFIRM_N:
        raise ValueError(f"need 1 <= M <= N <= {MAX_CONFIRM_N}, got M = {m}, N = {n}")
    pd = np.ascontiguousarray(pd, dtype=np.float64)
    out = np.zeros((pd.shape[0], pd.shape[1] + 1))
    _, miss, hit = _chain_tables(int(m), int(n))
    _first_confirmation_kernel(
        pd,
        np.ascontiguousarray(n_valid, dtype=np.int64),
        np.arange(pd.shape[0], dtype=np.int64),
        miss,
        hit,
        out,
    )
    return out


# --------------------------------------------------------------------------- braking


@njit(nogil=True)
def lost_distance(tau: float, v0: float, jerk: float, amax: float) -> float:  # pragma: no cover
    """Distance, m, the braking ego falls behind its planned constant-speed progress
    ``tau`` s after brake onset: ``v0 tau - d(tau)``, ``d`` the jerk-limited braking
    distance (deceleration ramps at ``jerk`` m/s3 to ``amax`` m/s2, then constant until
    standstill; ``v0`` m/s)."""
    if tau <= 0.0 or v0 <= 0.0:
        return 0.0
    t1 = amax / jerk
    if 0.5 * jerk * t1 * t1 >= v0:  # stops during the ramp
        ts = math.sqrt(2.0 * v0 / jerk)
        if tau <= ts:
            return jerk * tau**3 / 6.0
        d_stop = v0 * ts - jerk * ts**3 / 6.0
        return v0 * tau - d_stop
    if tau <= t1:
        return jerk * tau**3 / 6.0
    v1 = v0 - 0.5 * jerk * t1 * t1
    d1 = v0 * t1 - jerk * t1**3 / 6.0
    ts = t1 + v1 / amax
    if tau <= ts:
        u = tau - t1
        return v0 * tau - (d1 + v1 * u - 0.5 * amax * u * u)
    return v0 * tau - (d1 + v1 * v1 / (2.0 * amax))


@njit(nogil=True)
def braked_speed(tau: float, v0: float, jerk: float, amax: float) -> float:  # pragma: no cover
    """Speed, m/s, ``tau`` s after brake onset from ``v0`` m/s (jerk-limited at ``jerk``
    m/s3 up to ``amax`` m/s2, never below 0)."""
    if tau <= 0.0:
        return v0
    t1 = amax / jerk
    if tau <= t1:
        return max(0.0, v0 - 0.5 * jerk * tau * tau)
    return max(0.0, v0 - 0.5 * jerk * t1 * t1 - amax * (tau - t1))


def stopping_distance(v0: float, latency_s: float, jerk: float, amax: float) -> float:
    """Distance, m, travelled from confirmation to standstill: ``v0 latency`` plus the
    jerk-limited braking distance from ``v0`` m/s (``jerk`` m/s3 up to ``amax`` m/s2)."""
    big = latency_s + math.sqrt(2.0 * v0 / jerk) + v0 / amax + amax / jerk + 1.0
    return v0 * big - float(lost_distance(big - latency_s, v0, jerk, amax))


@njit(nogil=True)
def _rel_speed(vb: float, h: float, th: float, tv: float) -> float:  # pragma: no cover
    """|ego velocity (speed ``vb`` along heading ``h``) - target velocity|, m/s."""
    dvx = vb * math.cos(h) - tv * math.cos(th)
    dvy = vb * math.sin(h) - tv * math.sin(th)
    return math.sqrt(dvx * dvx + dvy * dvy)


@njit(nogil=True)
def after_horizon(
    gap: float,
    w: float,
    t_end: float,
    t_brake: float,
    v0: float,
    jerk: float,
    amax: float,
) -> tuple[float, float]:  # pragma: no cover - compiled
    """Relative impact speed, m/s, and contact time, s, of an encounter that the time axis
    ends before it is decided ((-1, inf): no collision): at ``t_end`` s the braking ego
    (planned speed ``v0`` m/s, braking from ``t_brake`` s, jerk-limited as
    ``lost_distance``) is ``gap`` m short of the target, which keeps its last speed ``w``
    m/s along the ego's path (one coming towards the ego, w < 0, is taken as standing: a
    lower bound of the impact). The ego closes in while it is faster than ``w``; contact
    when the distance it closes reaches ``gap`` (the time found by bisection to 1e-9 s);
    the impact speed is its speed then minus ``w``. The caller checks that the target is
    still in the ego's path at the contact time (``Encounter.exit_s``)."""
    if not (gap > 0.0) or math.isnan(w):
        return -1.0, np.inf
    # a target coming towards the ego (or jitter of its interval on a curve) is taken as
    # standing: the collision is not missed, its impact speed is a lower bound
    w = max(w, 0.0)
    if braked_speed(t_end - t_brake, v0, jerk, amax) <= w:
        return -1.0, np.inf  # slower than the target already: it only falls back
    t1 = amax / jerk
    v1 = v0 - 0.5 * jerk * t1 * t1
    # when the ego's speed is down to w: during the jerk ramp, or after it at amax
    tau_w = math.sqrt(2.0 * max(v0 - w, 0.0) / jerk) if w >= v1 else t1 + (v1 - w) / amax
    t_w = t_brake + tau_w  # when its speed is down to w (after t_end: faster at t_end)
    # distance closed on the target from t_end to tt: the ego's progress minus w (tt - t_end)
    p0 = v0 * t_end - lost_distance(t_end - t_brake, v0, jerk, amax)
    if (v0 * t_w - lost_distance(t_w - t_brake, v0, jerk, amax) - p0) - w * (t_w - t_end) < gap:
        return -1.0, np.inf
    a, b = t_end, t_w
    for _ in range(80):
        m = 0.5 * (a + b)
        if (v0 * m - lost_distance(m - t_brake, v0, jerk, amax) - p0) - w * (m - t_end) >= gap:
            b = m
        else:
            a = m
        if b - a <= 1e-9:
            break
    return max(braked_speed(b - t_brake, v0, jerk, amax) - w, 0.0), b


@njit(nogil=True)
def _reaction_kernel(
    lo: F64,
    hi: F64,
    v0: F64,
    threat: I64,
    collide: I64,
    f: F64,
    eh: F64,
    th: F64,
    tv: F64,
    dt: float,
    latency: float,
    jerk: float,
    amax: F64,
    pstep: I64,
    exit_s: F64,
    wanted: NDArray[np.bool_],
    out_p: F64,
    out_v: F64,
    out_perfect: F64,
    out_safe: F64,
    out_vperf: F64,
    out_med: F64,
    out_never: F64,
) -> None:  # pragma: no cover - compiled
    b, t = lo.shape
    lg = np.empty(t + 1)
    first = np.empty(t + 1, dtype=np.int64)
    nxt = np.empty(t + 2, dtype=np.int64)
    post_v = np.zeros(t + 1)
    for r in range(b):
        kc = collide[r]
        kt = threat[r]
        step = v0[r] * dt
        v_never = 0.0
        if kc >= 0:
            v_never = _rel_speed(v0[r], eh[r, kc], th[r, kc], tv[r, kc])
        out_med[r] = np.nan
        out_never[r] = np.nan
        if kc < 0 or kt < 0 or v0[r] < MIN_EGO_SPEED_M_S or not wanted[r]:
            # nothing to avoid (no open-loop collision), never a threat, nothing to brake
            # (or not asked for): every onset gives the open-loop outcome
            hit = 1.0 if kc >= 0 else 0.0
            out_p[r] = hit
            out_v[r] = v_never
            out_perfect[r] = hit
            out_vperf[r] = v_never
            out_safe[r] = np.nan if kc >= 0 else (t - 1) * dt
            continue
        # lost distance of step j behind onset step ko: lg[j - ko] (onsets ko in [kt, kc])
        n_lg = t - kt
        for mm in range(n_lg):
            lg[mm] = lost_distance(mm * dt - latency, v0[r], jerk, amax[r])
        for k in range(kt, kc + 1):
            first[k] = -1
            nxt[k] = k
        nxt[kc + 1] = kc + 1  # sentinel
        unset = kc - kt + 1
        g_lo = -1  # the last step's search results (starting guesses)
        g_hi = -1
        for j in range(kt, t):
            if unset == 0:
                break
            a0 = lo[r, j]
            if np.isnan(a0):
                continue
            pj = step * j
            bb = pj - a0  # lost distance at most this: the ego reaches the target's rear
            if bb < 0.0:
                continue
            a = pj - hi[r, j]  # and at least this: the ego is not yet past it
            m_min = j - min(j, kc)
            m_max = j - kt
            if lg[m_max] < a or lg[m_min] > bb:
                continue
            # m_lo: the first mm in [m_min, m_max] with lg[mm] >= a (lg is non-decreasing);
            # walk from the last step's answer + 1 (one more step of lag), else bisect
            x = min(max(g_lo + 1, m_min), m_max + 1)
            found = False
            for _ in range(6):
                if x > m_min and lg[x - 1] >= a:
                    x -= 1
                elif x <= m_max and lg[x] < a:
                    x += 1
                else:
                    found = True
                    break
            if not found:
                x0, x1 = m_min, m_max + 1
                while x0 < x1:
                    mid = (x0 + x1) // 2
                    if lg[mid] >= a:
                        x1 = mid
                    else:
                        x0 = mid + 1
                x = x0
            m_lo = x
            g_lo = m_lo
            # m_hi: the last mm in [m_lo, m_max] with lg[mm] <= bb
            x = min(max(g_hi + 2, m_lo), m_max + 1)
            found = False
            for _ in range(6):
                if x > m_lo and lg[x - 1] > bb:
                    x -= 1
                elif x <= m_max and lg[x] <= bb:
                    x += 1
                else:
                    found = True
                    break
            if not found:
                x0, x1 = m_lo, m_max + 1
                while x0 < x1:
                    mid = (x0 + x1) // 2
                    if lg[mid] > bb:
                        x1 = mid
                    else:
                        x0 = mid + 1
                x = x0
            m_hi = x - 1
            g_hi = m_hi
            if m_hi < m_lo:
                continue
            # fill the unset onsets of [j - m_hi, j - m_lo] (nxt: the next unset onset at
            # or after k, path-compressed: each onset is set once)
            kk = j - m_hi
            while True:
                root = kk
                while nxt[root] != root:
                    root = nxt[root]
                while nxt[kk] != root:
                    k2 = nxt[kk]
                    nxt[kk] = root
                    kk = k2
                kk = root
                if kk > j - m_lo:
                    break
                first[kk] = j
                unset -= 1
                nxt[kk] = kk + 1
                kk += 1
        # onsets that avoid the target within the time axis only because it ends first:
        # the encounter continues (the target at its last speed along the path, the ego
        # braking on; ``after_horizon``): a collision after the end is marked step t
        if unset > 0:
            e = t - 1
            w = np.nan
            if e >= 1 and not np.isnan(lo[r, e]) and not np.isnan(lo[r, e - 1]):
                w = (lo[r, e] - lo[r, e - 1]) / dt
            if w == w:
                for ko in range(kt, kc + 1):
                    if first[ko] >= 0:
                        continue
                    t_b = ko * dt + latency
                    gap = lo[r, e] - (step * e - lost_distance(e * dt - t_b, v0[r], jerk, amax[r]))
                    vh, tc = after_horizon(gap, w, e * dt, t_b, v0[r], jerk, amax[r])
                    # a target crossing the path collides only if still in it by then
                    if vh >= 0.0 and tc - e * dt <= exit_s[r]:
                        first[ko] = t
                        post_v[ko] = vh
        # outcome per confirmation step k (onset step ko = max(k, kt)); onsets after the
        # open-loop collision come too late and collide there
        p_col = 0.0
        v_sum = 0.0
        safe = -1
        still_safe = True
        out_perfect[r] = 0.0
        out_vperf[r] = 0.0
        cum = 0.0
        med = -1
        ps = pstep[r]  # the step at which perfect perception confirms (-1: never)
        v_ko = -1.0
        ko_last = -1
        # cos/sin of the last ego and target headings (nearby onsets: angle addition)
        eh0, ec0, es0 = np.nan, 1.0, 0.0
        th0, tc0, ts0 = np.nan, 1.0, 0.0
        for k in range(t):
            fk = f[r, k]
            if med < 0:
                cum += fk
                if cum >= 0.5:
                    med = k
            ko = max(k, kt)
            j = kc if ko > kc else first[ko]
            if j < 0:
                if still_safe:
                    safe = k
                continue
            still_safe = False
            if fk == 0.0 and k != ps:
                continue
            if ko > kc:
                v = v_never
            elif j == t:  # after the end of the time axis (above)
                v = post_v[ko]
            elif ko == ko_last:
                v = v_ko
            else:
                tau = (j - ko) * dt - latency
                vb = braked_speed(tau, v0[r], jerk, amax[r])
                # the ego's heading at its braked progress (linear between samples)
                x = (step * j - lg[j - ko]) / step
                i0 = min(max(int(x), 0), t - 1)
                h = eh[r, i0]
                if x > 0.0 and i0 < t - 1:
                    d = eh[r, i0 + 1] - h
                    h += (x - i0) * (d - 2.0 * math.pi * math.floor(d / (2.0 * math.pi) + 0.5))
                if h != eh0:
                    ec0, es0 = cos_sin_near(h, eh0, ec0, es0)
                    eh0 = h
                if th[r, j] != th0:
                    tc0, ts0 = cos_sin_near(th[r, j], th0, tc0, ts0)
                    th0 = th[r, j]
                dvx = vb * ec0 - tv[r, j] * tc0
                dvy = vb * es0 - tv[r, j] * ts0
                v = math.sqrt(dvx * dvx + dvy * dvy)
                v_ko = v
                ko_last = ko
            p_col += fk
            v_sum += fk * v
            if k == ps:
                out_perfect[r] = 1.0
                out_vperf[r] = v
        if ps < 0 or ps >= t:  # perfect perception never confirms on this time axis
            out_perfect[r] = 1.0
            out_vperf[r] = v_never
        p_col += f[r, t]
        v_sum += f[r, t] * v_never
        out_p[r] = min(max(p_col, 0.0), 1.0)
        out_v[r] = v_sum / p_col if p_col > 0.0 else 0.0
        out_safe[r] = safe * dt if safe >= 0 else np.nan
        out_med[r] = med * dt if med >= 0 else np.nan
        out_never[r] = f[r, t]


@dataclass(frozen=True)
class Outcome:
    """Collision outcome of B candidates, (B,) float arrays (module docstring).

    Attributes:
        collision_probability: P(collision) over the first-confirmation distribution, 0..1.
        impact_speed_kmh: expected relative impact speed given a collision, km/h (0 when
            the collision probability is 0).
        collision_perfect: 1 if perfect perception (Pd = 1) with the same reaction still
            collides, else 0. impact_speed_perfect_kmh: its impact speed, km/h (0: none).
        t_safe_s: latest confirmation time that (with every earlier one) avoids the
            collision, s (NaN: even step 0 collides).
        t_confirm_median_s: median first-confirmation time, s (NaN: P(confirmed) < 1/2,
            or no collision to avoid).
        detection_margin_s: ``t_safe_s - t_confirm_median_s``, s (NaN if either is).
        t_threat_s: threat onset, s (NaN: never a threat).
        p_never_confirmed: P(never confirmed within the valid steps), 0..1 (NaN: no
            collision to avoid).
        perfect_margin_s: how much later than perfect perception a confirmation may come
            and still avoid the collision, ``t_safe_s`` minus the reference's confirmation
            time, s (NaN: perfect perception collides too).
    """

    collision_probability: F64
    impact_speed_kmh: F64
    collision_perfect: F64
    impact_speed_perfect_kmh: F64
    t_safe_s: F64
    t_confirm_median_s: F64
    detection_margin_s: F64
    t_threat_s: F64
    p_never_confirmed: F64
    perfect_margin_s: F64


def reaction_outcome(
    enc: Encounter,
    pd_confirm: ArrayLike,
    n_valid: ArrayLike,
    confirm_m: int,
    confirm_n: int,
    latency_s: float,
    jerk_m_s3: float,
    decel_m_s2: ArrayLike,
    perfect_step: ArrayLike | None = None,
    rows: ArrayLike | None = None,
) -> Outcome:
    """The collision outcome of an encounter for (B, T) per-step Pd of the confirming
    sensors (only the first ``n_valid`` (B,) steps count), M-of-N confirmation, latency
    ``latency_s`` s, brake jerk ``jerk_m_s3`` m/s3 and ``decel_m_s2`` (B,) (or a scalar),
    the reachable deceleration ``min(decel_max, mu g)`` per row, m/s2. ``perfect_step``
    (B,): the step at which perfect perception confirms the target (-1: never; default
    ``confirm_m - 1``, seen at every step; ``coverage.sightline`` limits it to the line of
    sight past occluders). ``rows`` (B,) bool: the rows whose confirmation and braking are
    worked out (default all); the others get the open-loop outcome, as a row with nothing
    to brake (the search's encounters it may not use, whose metrics it sets to 0)."""
    b, t = enc.lo.shape
    if not 1 <= confirm_m <= confirm_n <= MAX_CONFIRM_N:
        raise ValueError(
            f"need 1 <= M <= N <= {MAX_CONFIRM_N}, got M = {confirm_m}, N = {confirm_n}"
        )
    if not (latency_s >= 0.0 and jerk_m_s3 > 0.0):
        raise ValueError("need latency_s >= 0 and jerk_m_s3 > 0")
    decel = np.ascontiguousarray(np.broadcast_to(np.asarray(decel_m_s2, dtype=np.float64), (b,)))
    if not np.all(decel > 0.0):
        raise ValueError("the reachable deceleration must be > 0 (mu > 0)")
    pd = np.ascontiguousarray(pd_confirm, dtype=np.float64)
    if pd.shape != (b, t):
        raise ValueError(f"pd_confirm has shape {pd.shape}, the encounter ({b}, {t})")
    # the confirmation distribution matters only where there is a collision to avoid
    wanted = (
        np.ones(b, dtype=np.bool_)
        if rows is None
        else np.ascontiguousarray(np.broadcast_to(np.asarray(rows, dtype=np.bool_), (b,)))
    )
    rows = np.flatnonzero(
        wanted & (enc.collide_step >= 0) & (enc.threat_step >= 0) & (enc.v0 >= MIN_EGO_SPEED_M_S)
    ).astype(np.int64)
    f = np.zeros((b, t + 1))
    if rows.size:
        _, miss, hit = _chain_tables(int(confirm_m), int(confirm_n))
        _first_confirmation_kernel(
            pd, np.ascontiguousarray(n_valid, dtype=np.int64), rows, miss, hit, f
        )
    pstep = (
        np.full(b, confirm_m - 1, dtype=np.int64)
        if perfect_step is None
        else np.ascontiguousarray(np.broadcast_to(np.asarray(perfect_step, dtype=np.int64), (b,)))
    )
    out = [np.empty(b) for _ in range(7)]
    _reaction_kernel(
        enc.lo,
        enc.hi,
        enc.v0,
        enc.threat_step,
        enc.collide_step,
        f,
        enc.ego_heading,
        enc.target_heading,
        enc.target_speed,
        enc.dt,
        float(latency_s),
        float(jerk_m_s3),
        decel,
        pstep,
        np.full(b, np.inf) if enc.exit_s is None else np.ascontiguousarray(enc.exit_s),
        wanted,
        *out,
    )
    p, v, perfect, safe, vperf, med, never = out
    # sums of probabilities that add up to 1 to rounding: kept within 0..1 (hostile round
    # fifteen: a stored p_never_confirmed of 1.0000000000000002 made the store "damaged")
    p, never = np.clip(p, 0.0, 1.0), np.minimum(never, 1.0)
    t_threat = np.where(enc.threat_step >= 0, enc.threat_step * enc.dt, np.nan)
    margin = np.where((perfect < 0.5) & (pstep >= 0), safe - pstep * enc.dt, np.nan)
    return Outcome(p, 3.6 * v, perfect, 3.6 * vperf, safe, med, safe - med, t_threat, never, margin)


def collision_outcome(
    ego: Tracks,
    target: Tracks,
    dt: float,
    target_size: tuple[float, float],
    ego_body: tuple[float, float, float],
    pd_confirm: ArrayLike,
    n_valid: ArrayLike,
    reaction: ReactionConfig,
    mu: float | ArrayLike,
) -> tuple[Encounter, Outcome]:
    """Both stages in one call: the encounter geometry of the (B, T) planned states of
    ``ego`` and ``target`` (see ``encounter_geometry`` for units) and the collision outcome
    for the confirming Pd, ``reaction`` (M-of-N, latency, jerk, decel_max, threat margin
    and horizon) and the road's peak friction ``mu`` (scalar or (B,)): deceleration
    ``min(decel_max, mu g)``."""
    enc = encounter_geometry(
        ego,
        target,
        dt,
        target_size,
        ego_body,
        reaction.threat_margin_m,
        reaction.threat_horizon_s,
        reaction.threat_prediction_s,
    )
    decel = np.minimum(reaction.decel_max_m_s2, np.asarray(mu, dtype=np.float64) * G_M_S2)
    return enc, reaction_outcome(
        enc,
        pd_confirm,
        n_valid,
        reaction.confirm_m,
        reaction.confirm_n,
        reaction.latency_s,
        reaction.jerk_m_s3,
        decel,
    )
