"""Criticality in collision terms: would the vehicle under test, with its sensors and its
reaction model, confirm the target in time to brake and avoid the collision?

Two stages over a batch of B candidates on one time axis (T steps of ``dt``):

1. **Encounter geometry** (``encounter_geometry``, sensor-independent). The ego drives its
   planned path at its planned speed ``v0`` (open loop; the families keep it constant), so
   its progress along the path is ``p_k = v0 t_k``. For every step j the target's box
   (4 corners) is put into the frame of the nearest ego path sample: lateral offsets ``v``
   and path-aligned offsets ``u``. When its lateral extent overlaps the ego's half width,
   the ego's rear axle overlaps the target at step j for progress ``q`` in
   ``[lo_j, hi_j] = [s + u_min - x_front, s + u_max - x_rear]`` (a box test in the path
   frame: exact on straight roads, a chord approximation in curves). The open-loop
   collision is the first step with ``p_j`` in that interval; the *path TTC* at step k is
   the time from ``t_k`` to it (inf without one): TTC follows the paths (curves,
   crossings). The *threat onset* is the first step at which the target's box, widened by
   ``threat_margin_m`` each side, overlaps the ego's path swept over the next
   ``threat_horizon_s`` (``[p_k + x_rear, p_k + x_front + v0 H]``).

2. **Reaction** (``reaction_outcome``). The target is *confirmed* at the first step at
   which at least M of the last N sensor cycles detected it (per-step Pd of the confirming
   sensors, independent cycles); the distribution of that first step is computed exactly
   by a Markov chain over the last N - 1 detection bits. The vehicle brakes at
   ``t_b = max(t_confirm, t_threat) + latency``: deceleration ramps up with jerk ``J`` to
   ``A = min(decel_max, mu g)`` (``mu``: the road's friction) and holds until standstill;
   it stays on its path, only its progress drops by ``L(tau) = v0 tau - d(tau)`` (``d``: the
   closed-form jerk-limited braking distance). Confirmation at step k collides
   (``c_k = 1``) when some step j has ``p_j - L(t_j - t_b)`` in ``[lo_j, hi_j]``: per step j
   the onsets that collide there form one interval (L is monotone), found by bisection,
   so all onsets cost O(T log T). Without confirmation the vehicle does not brake
   (``c_never``: the open-loop collision).

Per candidate: ``collision_probability = sum_k f_k c_k + f_never c_never`` (f: the
first-confirmation distribution; exact, no monotonicity assumed), ``impact_speed_kmh``
(expected relative speed at the first overlap given a collision), ``collision_perfect``
(``c`` for perfect perception: Pd = 1 every step, confirmed at step M - 1), ``t_safe_s``
(the latest ``t_k`` such that confirmation at any step up to k avoids the collision; NaN if
none does), ``detection_margin_s`` (``t_safe`` minus the median confirmation time; NaN
when either is undefined), ``t_threat_s``, ``t_confirm_median_s`` and
``p_never_confirmed`` (the last two only where there is a collision to avoid: an open-loop
collision after a threat onset; NaN elsewhere). An encounter without
an open-loop collision has nothing to avoid: collision probability 0 (braking for a near
miss, which could turn it into a collision, is left to the planner).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: Standard gravity, m/s2.
G_M_S2 = 9.80665
#: Below this planned ego speed braking cannot change the encounter, m/s.
MIN_EGO_SPEED_M_S = 0.1


@dataclass(frozen=True)
class Encounter:
    """Encounter geometry of B candidates (see the module docstring).

    Attributes:
        lo, hi: (B, T) ego rear-axle progress (m) at which the ego would overlap the
            target at step j (NaN where the target is not laterally in the ego's path).
        progress: (B, T) planned ego progress p_k, m. v0: (B,) planned ego speed, m/s.
        collide_step: (B,) first open-loop overlap step (-1: none).
        threat_step: (B,) threat onset step (-1: never a threat).
        ttc_path: (B, T) time to the open-loop collision along the paths, s (inf: none;
            0 from the collision on).
    """

    lo: F64
    hi: F64
    progress: F64
    v0: F64
    collide_step: I64
    threat_step: I64
    ttc_path: F64
    ego_heading: F64
    target_vx: F64
    target_vy: F64
    dt: float


@numba.njit(cache=True, nogil=True)
def _geometry_kernel(ex: F64, ey: F64, eh: F64, v0: F64, tx: F64, ty: F64, th: F64,
                     length: float, width: float, x_front: float, x_rear: float,
                     half_w: float, margin: float, horizon: float, dt: float,
                     tv: F64, lo: F64, hi: F64, progress: F64, collide: I64,
                     threat: I64, ttc: F64, vx: F64, vy: F64
                     ) -> None:  # pragma: no cover - compiled
    b, t = ex.shape
    cl = np.empty(4)
    cw = np.empty(4)
    cl[0], cl[1], cl[2], cl[3] = 0.5 * length, 0.5 * length, -0.5 * length, -0.5 * length
    cw[0], cw[1], cw[2], cw[3] = 0.5 * width, -0.5 * width, -0.5 * width, 0.5 * width
    half_diag = 0.5 * math.sqrt(length * length + width * width)
    for r in range(b):
        collide[r] = -1
        threat[r] = -1
        step = v0[r] * dt
        for k in range(t):
            progress[r, k] = v0[r] * dt * k
        i = 0
        for j in range(t):
            # nearest ego path sample to the target centre (hill-climb from the last one)
            best = (ex[r, i] - tx[r, j]) ** 2 + (ey[r, i] - ty[r, j]) ** 2
            while i + 1 < t:
                d = (ex[r, i + 1] - tx[r, j]) ** 2 + (ey[r, i + 1] - ty[r, j]) ** 2
                if d >= best:
                    break
                best = d
                i += 1
            while i > 0:
                d = (ex[r, i - 1] - tx[r, j]) ** 2 + (ey[r, i - 1] - ty[r, j]) ** 2
                if d >= best:
                    break
                best = d
                i -= 1
            c = math.cos(eh[r, i])
            s = math.sin(eh[r, i])
            ct = math.cos(th[r, j])
            st = math.sin(th[r, j])
            vx[r, j] = tv[r, j] * ct
            vy[r, j] = tv[r, j] * st
            # far beside the path (centre farther than the widths, margin and the box's
            # half diagonal): neither overlap nor threat at this step
            vc = -s * (tx[r, j] - ex[r, i]) + c * (ty[r, j] - ey[r, i])
            if abs(vc) > half_w + margin + half_diag:
                lo[r, j] = np.nan
                hi[r, j] = np.nan
                continue
            umin, umax, vmin, vmax = 1e300, -1e300, 1e300, -1e300
            for q in range(4):
                px = tx[r, j] + ct * cl[q] - st * cw[q] - ex[r, i]
                py = ty[r, j] + st * cl[q] + ct * cw[q] - ey[r, i]
                u = c * px + s * py
                v = -s * px + c * py
                umin = min(umin, u)
                umax = max(umax, u)
                vmin = min(vmin, v)
                vmax = max(vmax, v)
            # the path position of sample i: its planned progress (v0 dt per step); a
            # stationary ego has one position
            s_i = step * i
            if vmax >= -half_w and vmin <= half_w:
                lo[r, j] = s_i + umin - x_front
                hi[r, j] = s_i + umax - x_rear
                if collide[r] < 0 and lo[r, j] <= progress[r, j] <= hi[r, j]:
                    collide[r] = j
            else:
                lo[r, j] = np.nan
                hi[r, j] = np.nan
            if threat[r] < 0 and vmax >= -half_w - margin and vmin <= half_w + margin:
                a0 = progress[r, j] + x_rear
                a1 = progress[r, j] + x_front + v0[r] * horizon
                if s_i + umax >= a0 and s_i + umin <= a1:
                    threat[r] = j
        c_step = collide[r]
        for k in range(t):
            if c_step < 0:
                ttc[r, k] = np.inf
            else:
                ttc[r, k] = max(c_step - k, 0) * dt


def encounter_geometry(ego_x: F64, ego_y: F64, ego_heading: F64, ego_speed: F64,
                       tgt_x: F64, tgt_y: F64, tgt_heading: F64, tgt_speed: F64,
                       dt: float, target_size: tuple[float, float],
                       ego_body: tuple[float, float, float], threat_margin_m: float,
                       threat_horizon_s: float) -> Encounter:
    """Encounter geometry of (B, T) world-frame states (m, rad, m/s): ego rear axle and
    target box centre. ``target_size`` = (length, width), m; ``ego_body`` = (x_front,
    x_rear, width), m, relative to the rear axle (x_rear < 0)."""
    ex = np.ascontiguousarray(ego_x, dtype=np.float64)
    b, t = ex.shape
    v0 = np.ascontiguousarray(np.asarray(ego_speed, dtype=np.float64)[:, 0])
    lo, hi, prog = np.empty((b, t)), np.empty((b, t)), np.empty((b, t))
    ttc, vx, vy = np.empty((b, t)), np.empty((b, t)), np.empty((b, t))
    collide = np.empty(b, dtype=np.int64)
    threat = np.empty(b, dtype=np.int64)
    x_front, x_rear, width = ego_body
    eh = np.ascontiguousarray(ego_heading, dtype=np.float64)
    _geometry_kernel(ex, np.ascontiguousarray(ego_y, dtype=np.float64), eh, v0,
                     np.ascontiguousarray(tgt_x, dtype=np.float64),
                     np.ascontiguousarray(tgt_y, dtype=np.float64),
                     np.ascontiguousarray(tgt_heading, dtype=np.float64),
                     float(target_size[0]), float(target_size[1]), float(x_front),
                     float(x_rear), 0.5 * float(width), float(threat_margin_m),
                     float(threat_horizon_s), float(dt),
                     np.ascontiguousarray(tgt_speed, dtype=np.float64), lo, hi, prog,
                     collide, threat, ttc, vx, vy)
    return Encounter(lo, hi, prog, v0, collide, threat, ttc, eh, vx, vy, float(dt))


@numba.njit(cache=True, nogil=True)
def first_confirmation_kernel(pd: F64, n_valid: I64, m: int, n: int,
                              out: F64) -> None:  # pragma: no cover - compiled
    """``out[r, k]`` = P(first M-of-N confirmation at step k), ``out[r, T]`` = P(none
    within the first ``n_valid[r]`` steps); exact Markov chain over the last N - 1 bits."""
    b, t = pd.shape
    n_states = 1 << (n - 1)
    mask_n = (1 << n) - 1
    mask_s = n_states - 1
    prob = np.empty(n_states)
    nxt = np.empty(n_states)
    for r in range(b):
        for s in range(n_states):
            prob[s] = 0.0
        prob[0] = 1.0
        for k in range(t + 1):
            out[r, k] = 0.0
        for k in range(n_valid[r]):
            p = min(max(pd[r, k], 0.0), 1.0)
            for s in range(n_states):
                nxt[s] = 0.0
            f = 0.0
            for s in range(n_states):
                q = prob[s]
                if q == 0.0:
                    continue
                w = ((s << 1) | 1) & mask_n
                cnt = 0
                x = w
                while x:
                    cnt += x & 1
                    x >>= 1
                if cnt >= m:
                    f += q * p
                else:
                    nxt[w & mask_s] += q * p
                nxt[(s << 1) & mask_s] += q * (1.0 - p)
            out[r, k] = f
            for s in range(n_states):
                prob[s] = nxt[s]
        rest = 0.0
        for s in range(n_states):
            rest += prob[s]
        out[r, t] = rest


def first_confirmation(pd: F64, n_valid: I64, m: int, n: int) -> F64:
    """(B, T + 1) distribution of the first M-of-N confirmation step of (B, T) per-step
    detection probabilities (independent cycles; only the first ``n_valid`` steps count);
    the last column is P(never confirmed)."""
    pd = np.ascontiguousarray(pd, dtype=np.float64)
    out = np.empty((pd.shape[0], pd.shape[1] + 1))
    first_confirmation_kernel(pd, np.ascontiguousarray(n_valid, dtype=np.int64), int(m),
                              int(n), out)
    return out


@numba.njit(cache=True, nogil=True)
def lost_distance(tau: float, v0: float, jerk: float, amax: float) -> float:  # pragma: no cover
    """Distance (m) the braking ego falls behind its planned constant-speed progress
    ``tau`` s after brake onset: ``v0 tau - d(tau)``, ``d`` the jerk-limited braking
    distance (ramp at ``jerk`` to ``amax``, then constant until standstill)."""
    if tau <= 0.0 or v0 <= 0.0:
        return 0.0
    t1 = amax / jerk
    if 0.5 * jerk * t1 * t1 >= v0:  # stops during the ramp
        ts = math.sqrt(2.0 * v0 / jerk)
        if tau <= ts:
            return jerk * tau ** 3 / 6.0
        d_stop = v0 * ts - jerk * ts ** 3 / 6.0
        return v0 * tau - d_stop
    if tau <= t1:
        return jerk * tau ** 3 / 6.0
    v1 = v0 - 0.5 * jerk * t1 * t1
    d1 = v0 * t1 - jerk * t1 ** 3 / 6.0
    ts = t1 + v1 / amax
    if tau <= ts:
        u = tau - t1
        return v0 * tau - (d1 + v1 * u - 0.5 * amax * u * u)
    return v0 * tau - (d1 + v1 * v1 / (2.0 * amax))


@numba.njit(cache=True, nogil=True)
def braked_speed(tau: float, v0: float, jerk: float, amax: float) -> float:  # pragma: no cover
    """Speed (m/s) ``tau`` s after brake onset (jerk-limited, never below 0)."""
    if tau <= 0.0:
        return v0
    t1 = amax / jerk
    if tau <= t1:
        return max(0.0, v0 - 0.5 * jerk * tau * tau)
    return max(0.0, v0 - 0.5 * jerk * t1 * t1 - amax * (tau - t1))


@numba.njit(cache=True, nogil=True)
def _next_unset(nxt: I64, k: int) -> int:  # pragma: no cover - compiled
    """The first index >= k with ``nxt[i] == i`` (path compression on the way)."""
    root = k
    while nxt[root] != root:
        root = nxt[root]
    while nxt[k] != root:
        k2 = nxt[k]
        nxt[k] = root
        k = k2
    return root


@numba.njit(cache=True, nogil=True)
def _reaction_kernel(lo: F64, hi: F64, prog: F64, v0: F64, threat: I64, collide: I64,
                     f: F64, eh: F64, tvx: F64, tvy: F64, dt: float, latency: float,
                     jerk: float, amax: F64, m: int, out_p: F64, out_v: F64,
                     out_perfect: F64, out_safe: F64, out_vperf: F64
                     ) -> None:  # pragma: no cover - compiled
    b, t = lo.shape
    lg = np.empty(t + 1)
    first = np.empty(t, dtype=np.int64)
    nxt = np.empty(t + 1, dtype=np.int64)
    for r in range(b):
        # c_never / v_never: the open-loop collision
        c_never = collide[r] >= 0
        v_never = 0.0
        if c_never:
            j = collide[r]
            dvx = v0[r] * math.cos(eh[r, j]) - tvx[r, j]
            dvy = v0[r] * math.sin(eh[r, j]) - tvy[r, j]
            v_never = math.sqrt(dvx * dvx + dvy * dvy)
        if not c_never or threat[r] < 0 or v0[r] < 0.1:
            # no open-loop collision (nothing to avoid: braking for a near miss is the
            # planner's choice, not a sensor's failure), never a threat, or nothing to
            # brake: every onset gives the open-loop outcome
            p_col = 0.0
            if c_never:
                p_col = 1.0
            out_p[r] = p_col
            out_v[r] = v_never if c_never else 0.0
            out_perfect[r] = 1.0 if c_never else 0.0
            out_vperf[r] = v_never if c_never else 0.0
            out_safe[r] = np.nan if c_never else (t - 1) * dt
            continue
        kt = threat[r]
        # onset of confirmation at step k: t_b = max(k, kt) * dt + latency; the lag of
        # step j behind it is (j - max(k, kt)) * dt - latency: tabulate L on that grid
        for mm in range(t + 1):
            lg[mm] = lost_distance(mm * dt - latency, v0[r], jerk, amax[r])
        for k in range(t):
            first[k] = -1
            nxt[k] = k
        nxt[t] = t
        # for each step j with a lateral overlap: onset steps k' (>= kt) with
        # lg[j - k'] in [prog_j - hi_j, prog_j - lo_j] collide at j
        for j in range(t):
            if np.isnan(lo[r, j]):
                continue
            a = prog[r, j] - hi[r, j]
            bb = prog[r, j] - lo[r, j]
            if bb < 0.0:
                continue
            # lg is non-decreasing in mm: mm range with lg in [a, bb]
            lo_i, hi_i = 0, j + 1
            while lo_i < hi_i:  # first mm with lg[mm] >= a
                mid = (lo_i + hi_i) // 2
                if lg[mid] >= a:
                    hi_i = mid
                else:
                    lo_i = mid + 1
            m_lo = lo_i
            lo_i, hi_i = 0, j + 1
            while lo_i < hi_i:  # first mm with lg[mm] > bb
                mid = (lo_i + hi_i) // 2
                if lg[mid] > bb:
                    hi_i = mid
                else:
                    lo_i = mid + 1
            m_hi = lo_i - 1
            if m_hi < m_lo:
                continue
            # first collision step per onset: fill the unset onsets of [a, b] (nxt: next
            # unset onset at or after k, path-compressed; each onset is set once)
            kk = _next_unset(nxt, max(j - m_hi, 0))
            while kk <= j - m_lo:
                first[kk] = j
                nxt[kk] = kk + 1
                kk = _next_unset(nxt, kk + 1)
        # an onset after the open-loop collision comes too late: it collides there
        if collide[r] >= 0:
            for kk in range(collide[r] + 1, t):
                first[kk] = collide[r]
        out_perfect[r] = 0.0
        out_vperf[r] = 0.0
        # outcome per confirmation step k (onset step max(k, kt))
        p_col = 0.0
        v_sum = 0.0
        safe = -1
        still_safe = True
        for k in range(t):
            ko = max(k, kt)
            j = first[ko]
            if j >= 0:
                still_safe = False
                tau = (j - ko) * dt - latency
                vb = braked_speed(tau, v0[r], jerk, amax[r])
                dvx = vb * math.cos(eh[r, j]) - tvx[r, j]
                dvy = vb * math.sin(eh[r, j]) - tvy[r, j]
                v = math.sqrt(dvx * dvx + dvy * dvy)
                p_col += f[r, k]
                v_sum += f[r, k] * v
                if k == m - 1:
                    out_perfect[r] = 1.0
                    out_vperf[r] = v
            else:
                if still_safe:
                    safe = k
        if c_never:
            p_col += f[r, t]
            v_sum += f[r, t] * v_never
        out_p[r] = min(max(p_col, 0.0), 1.0)
        out_v[r] = v_sum / p_col if p_col > 0.0 else 0.0
        out_safe[r] = safe * dt if safe >= 0 else np.nan


@dataclass(frozen=True)
class Outcome:
    """Collision outcome of B candidates (see the module docstring), (B,) arrays."""

    collision_probability: F64
    impact_speed_kmh: F64
    collision_perfect: F64
    impact_speed_perfect_kmh: F64
    t_safe_s: F64
    t_confirm_median_s: F64
    detection_margin_s: F64
    t_threat_s: F64
    p_never_confirmed: F64


def reaction_outcome(enc: Encounter, pd_confirm: F64, n_valid: I64, confirm_m: int,
                     confirm_n: int, latency_s: float, jerk_m_s3: float,
                     decel_m_s2: F64) -> Outcome:
    """The collision outcome of an encounter for per-step confirming Pd (B, T), the
    first ``n_valid`` steps valid; ``decel_m_s2`` (B,): the reachable deceleration
    ``min(decel_max, mu g)`` per row, m/s2."""
    b, t = enc.lo.shape
    # the confirmation distribution matters only where there is a collision to avoid;
    # elsewhere its summaries are not computed (NaN)
    rows = np.flatnonzero((enc.collide_step >= 0) & (enc.threat_step >= 0))
    f = np.zeros((b, t + 1))
    if rows.size:
        f[rows] = first_confirmation(np.asarray(pd_confirm)[rows],
                                     np.asarray(n_valid)[rows], confirm_m, confirm_n)
    out = [np.empty(b) for _ in range(5)]
    _reaction_kernel(enc.lo, enc.hi, enc.progress, enc.v0, enc.threat_step,
                     enc.collide_step, f, enc.ego_heading, enc.target_vx, enc.target_vy,
                     enc.dt, float(latency_s), float(jerk_m_s3),
                     np.ascontiguousarray(decel_m_s2, dtype=np.float64), int(confirm_m),
                     *out)
    p, v, perfect, safe, vperf = out
    med = np.full(b, np.nan)
    never = np.full(b, np.nan)
    if rows.size:
        cum = np.cumsum(f[rows, :t], axis=1)
        reached = cum[:, -1] >= 0.5
        med[rows] = np.where(reached, np.argmax(cum >= 0.5, axis=1) * enc.dt, np.nan)
        never[rows] = f[rows, t]
    margin = safe - med
    return Outcome(p, 3.6 * v, perfect, 3.6 * vperf, safe, med, margin,
                   np.where(enc.threat_step >= 0, enc.threat_step * enc.dt, np.nan), never)
