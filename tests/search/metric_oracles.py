"""Reference (numpy, one trace at a time) implementations of the built-in metrics: the
oracles the compiled batch pass (``search.fastmetrics`` via ``metrics.summary``) is tested
against. They are the former per-trace ``Metric.compute`` methods, kept here so that the
package holds one implementation per metric (issue #16)."""

from __future__ import annotations

import functools

import numpy as np

from sensorgap.search.evaluate import Trace
from sensorgap.search.metrics import (
    CAP_S,
    LOW_PD,
    log10_risk_profile,
    risk_profile,
)


def at_least_m_of_window(pd: np.ndarray, m: int, n: int) -> np.ndarray:
    """P(at least m detections among the last n cycles) at every step (Poisson-binomial
    over the window of independent cycles; shorter windows at the start)."""
    pd = np.ascontiguousarray(pd)
    # every metric's oracle asks for the detection step of the same trace: computed once
    # per (Pd series, m, n), a copy returned
    return _m_of_window(pd.tobytes(), pd.dtype.str, pd.shape, m, n).copy()


@functools.lru_cache(maxsize=256)
def _m_of_window(pd_bytes: bytes, dtype: str, shape: tuple[int, ...], m: int, n: int) -> np.ndarray:
    pd = np.frombuffer(pd_bytes, dtype=dtype).reshape(shape)
    out = np.zeros(pd.size)
    for k in range(pd.size):
        window = pd[max(0, k - n + 1) : k + 1]
        dist = np.zeros(window.size + 1)  # dist[j] = P(j detections so far)
        dist[0] = 1.0
        for p in window:
            dist[1:] = dist[1:] * (1.0 - p) + dist[:-1] * p
            dist[0] *= 1.0 - p
        out[k] = float(dist[m:].sum()) if m <= window.size else 0.0
    return out


def detection_index(tr: Trace) -> int | None:
    """First step at which the target counts as reliably detected under ``tr.rule``
    (cumulative Pd >= threshold, or M-of-N confirmation), or None."""
    rule = tr.rule
    if rule.kind == "cumulative":
        hit = np.flatnonzero(tr.p_undetected <= 1.0 - rule.threshold)
    else:
        hit = np.flatnonzero(at_least_m_of_window(tr.pd, rule.m, rule.n) >= rule.threshold)
    return int(hit[0]) if hit.size else None


def corridor(tr: Trace, threshold: float = LOW_PD) -> tuple[int, int]:
    """Longest contiguous run of steps with Pd < threshold: [start, end) (0, 0 if none)."""
    low = np.concatenate([[False], tr.pd < threshold, [False]])
    edges = np.flatnonzero(np.diff(low.astype(np.int8)))
    if edges.size == 0:
        return 0, 0
    starts, ends = edges[0::2], edges[1::2]
    i = int(np.argmax(ends - starts))
    return int(starts[i]), int(ends[i])


def _cap(v: float) -> float:
    return float(min(v, CAP_S))


def _at_detection(tr: Trace, values: np.ndarray, cap: bool = True) -> float:
    k = detection_index(tr)
    v = float(np.min(values)) if k is None else float(values[k])
    return _cap(v) if cap else v


def _corridor_duration(tr: Trace) -> float:
    """From the time of the corridor's first step to that of the step after its last, or
    to the end of the time axis when it runs to the last step (s)."""
    a, b = corridor(tr)
    if b <= a:
        return 0.0
    end = tr.t[b] if b < len(tr.t) else tr.t[-1]
    return float(end - tr.t[a])


def _corridor_point(tr: Trace, index: int, coord: str) -> float:
    a, b = corridor(tr)
    if b == a:
        return 0.0
    k = a if index == 0 else b - 1
    return float((tr.x if coord == "x" else tr.y)[k])


def oracle(name: str, tr: Trace) -> float:
    """The built-in metric ``name`` of one trace, by the reference formulas."""
    k = detection_index(tr)
    table = {
        "risk": lambda: float(np.max(risk_profile(tr))),
        "log10_risk": lambda: float(np.max(log10_risk_profile(tr))),
        "p_undetected_end": lambda: float(tr.p_undetected[-1]),
        "detected": lambda: 0.0 if k is None else 1.0,
        "t_detect_s": lambda: tr.duration_s if k is None else float(tr.t[k]),
        "ttc_at_detect_s": lambda: _at_detection(tr, tr.ttc),
        "headway_at_detect_s": lambda: _at_detection(tr, tr.headway),
        "distance_at_detect_m": lambda: _at_detection(tr, tr.distance, cap=False),
        "min_ttc_s": lambda: _cap(float(np.min(tr.ttc))),
        "mean_pd": lambda: float(np.mean(tr.pd)),
        "corridor_s": lambda: _corridor_duration(tr),
        "corridor_t0_s": lambda: float(tr.t[corridor(tr)[0]]),
        "corridor_x0_m": lambda: _corridor_point(tr, 0, "x"),
        "corridor_y0_m": lambda: _corridor_point(tr, 0, "y"),
        "corridor_x1_m": lambda: _corridor_point(tr, 1, "x"),
        "corridor_y1_m": lambda: _corridor_point(tr, 1, "y"),
    }
    if name in table:
        return table[name]()
    return float(tr.extra[name])  # the collision outcome's fields (search.outcome)
