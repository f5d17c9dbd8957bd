"""Compiled (numba) per-row summary of a ``BatchTrace``: one pass over each row's steps
gives every built-in metric (same definitions as the per-trace functions of
``search.metrics``, which remain the reference; tested equal to 1e-12)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.jit import njit

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]

#: Columns of the float output of ``summarize``.
COLUMNS = (
    "risk",
    "log10_risk",
    "p_undetected_end",
    "mean_pd",
    "min_ttc",
    "ttc_at",
    "headway_at",
    "distance_at",
    "min_distance",
    "log10_risk_raw",
)


@njit(nogil=True)
def summarize(
    log_miss: F64,
    ttc: F64,
    headway: F64,
    distance: F64,
    t: F64,
    n: I64,
    det_given: I64,
    cumulative: bool,
    threshold: float,
    lead_in: float,
    tau: float,
    low_pd: float,
    floor: float,
    out: F64,
    idx: I64,
) -> None:  # pragma: no cover - compiled
    """Per row i of (B, T) arrays, over its first ``n[i]`` steps:

    ``idx[i]`` = (detection step or -1, corridor start, corridor end) where detection is
    the first step with ``exp(cumsum(log_miss)) <= 1 - threshold`` (``cumulative``) or
    ``det_given[i]``; the corridor the first longest run of steps with Pd < ``low_pd``,
    [start, end), (0, 0) if none. ``out[i]`` = ``COLUMNS``: max over steps with
    t >= ``lead_in`` of P_undet exp(-TTC / tau); the same in log10 over steps with a
    finite TTC (``floor`` otherwise); P_undet at the last step; mean Pd; min TTC; TTC,
    headway and distance at detection (their minimum over the steps if never detected);
    min distance; log10 risk without the floor (-inf without a finite TTC).
    """
    inv_ln10 = 1.0 / math.log(10.0)
    inv_tau = 1.0 / tau  # (multiplying: a division per step took longer)
    limit = 1.0 - threshold
    for i in range(log_miss.shape[0]):
        m = n[i]
        lu = 0.0
        det = -1 if cumulative else det_given[i]
        # the largest ln(P_undet) - TTC / tau over the scored steps: the risk is its exp (exp
        # being monotone, one exp per row instead of two per step; the same up to rounding)
        top = -np.inf
        sum_pd = 0.0
        min_ttc = np.inf
        min_hw = np.inf
        min_dist = np.inf
        run = 0
        best = 0
        best_end = 0
        for k in range(m):
            lm = log_miss[i, k]
            lu += lm
            # (rows the lookup skipped hold ln P_miss = 0 and TTC = inf at every step: the
            # guards below skip their exponentials, with the same results)
            if det < 0 and cumulative and (lu != 0.0 or limit >= 1.0) and math.exp(lu) <= limit:
                det = k
            pd = -math.expm1(lm) + 0.0 if lm != 0.0 else 0.0
            sum_pd += pd
            tk = ttc[i, k]
            if t[k] >= lead_in and tk < np.inf:  # exp(-inf) = 0: no risk at this step
                top = max(top, lu - tk * inv_tau)
            min_ttc = min(min_ttc, tk)
            min_hw = min(min_hw, headway[i, k])
            min_dist = min(min_dist, distance[i, k])
            if pd < low_pd:
                run += 1
                if run > best:
                    best = run
                    best_end = k + 1
            else:
                run = 0
        lraw = top * inv_ln10
        out[i, 0] = math.exp(top)
        out[i, 1] = max(lraw, floor)
        out[i, 2] = math.exp(lu)
        out[i, 3] = sum_pd / m
        out[i, 4] = min_ttc
        if det >= 0:
            out[i, 5] = ttc[i, det]
            out[i, 6] = headway[i, det]
            out[i, 7] = distance[i, det]
        else:
            out[i, 5] = min_ttc
            out[i, 6] = min_hw
            out[i, 7] = min_dist
        out[i, 8] = min_dist
        out[i, 9] = lraw
        idx[i, 0] = det
        idx[i, 1] = best_end - best if best > 0 else 0
        idx[i, 2] = best_end if best > 0 else 0
