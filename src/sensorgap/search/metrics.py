"""Metrics of an evaluated scenario (``Trace``): classes with a direction, by name.

``better`` says which way is *more critical* (what the search looks for): ``higher`` or
``lower``; ``none`` marks descriptive values (where a corridor lies). Every metric returns
a finite float (infinite TTC/headway are capped at ``CAP_S``).

Risk (the ranking score)::

    risk = max_{k: t_k >= LEAD_IN_S}  P_undet(t_k) * exp(-TTC_k / TAU_S)

with ``P_undet(t_k) = prod_{j<=k} (1 - Pd_j)`` (independent steps at 20 Hz) and TTC the
longitudinal time to collision of an in-path target (0 once the boxes overlap, inf when
not in path or not closing). It is the probability that the target is still undetected,
weighted by how imminent a collision is at that moment: 1 = undetected at impact,
~0.37 = undetected 2 s before impact, 0 = detected before it ever got close or never a
threat. With independent 20 Hz steps the risk underflows towards 0 for most scenarios, so
ranking and search use ``log10_risk`` (the same quantity in the log domain, floor -300),
which keeps scenarios ordered by how close they come to an undetected threat.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar, Literal, TypeVar

import numpy as np

from sensorgap.plugins import load_plugins
from sensorgap.registry import Registry
from sensorgap.scenarios.trajectory import DT_S
from sensorgap.search.evaluate import BatchTrace, Trace
from sensorgap.search.fastmetrics import COLUMNS, summarize

#: Time constant of the imminence weight of the risk, s.
TAU_S = 2.0
#: Lead-in: the risk is assessed from this time on, s. Detections during the lead-in count
#: (P_undet runs from t = 0), but a scenario is not scored on its first frames, where
#: P_undet is a single miss of the initial placement rather than a failure to detect over
#: time (20 sensor cycles at 20 Hz).
LEAD_IN_S = 1.0
#: Per-step Pd below which a step belongs to a low-detection corridor.
LOW_PD = 0.5
#: Cap for infinite TTC / headway, s.
CAP_S = 99.0


def detection_index_batch(bt: BatchTrace) -> np.ndarray:
    """(B,) ``detection_index`` of every row, -1 where never detected (cached)."""
    return summary(bt).detection


def corridor_batch(bt: BatchTrace, threshold: float = LOW_PD) -> tuple[np.ndarray, np.ndarray]:
    """(B,) ``corridor`` of every row: [start, end) of the first longest low-Pd run."""
    if threshold == LOW_PD:
        sm = summary(bt)
        return sm.corridor_start, sm.corridor_end
    low = (bt.pd < threshold) & bt.valid
    c = np.cumsum(low, axis=1)
    run: np.ndarray = c - np.maximum.accumulate(np.where(low, 0, c), axis=1)
    end = np.argmax(run, axis=1)
    length: np.ndarray = run[np.arange(len(run)), end]
    start = np.where(length > 0, end - length + 1, 0)
    return start, np.where(length > 0, end + 1, 0)


def risk_profile(tr: Trace) -> np.ndarray:
    """P_undet(t_k) * exp(-TTC_k / TAU_S) per step (0 during the lead-in)."""
    prof = tr.p_undetected * np.exp(-tr.ttc / TAU_S)
    return np.asarray(np.where(tr.t >= LEAD_IN_S, prof, 0.0), dtype=np.float64)


#: log10 of the risk reported when the target never becomes a threat (no finite TTC).
LOG10_RISK_FLOOR = -300.0


def log10_risk_profile(tr: Trace) -> np.ndarray:
    """log10(P_undet(t_k) exp(-TTC_k / TAU_S)) per step, computed in the log domain so that
    it stays finite and ordered where the risk itself underflows (e.g. 1e-40); steps without
    a finite TTC sit at ``LOG10_RISK_FLOOR``."""
    ln = tr.log_undetected - np.where(np.isfinite(tr.ttc), tr.ttc, 0.0) / TAU_S
    assessed = np.isfinite(tr.ttc) & (tr.t >= LEAD_IN_S)
    out = np.where(assessed, ln / math.log(10.0), LOG10_RISK_FLOOR)
    return np.asarray(np.maximum(out, LOG10_RISK_FLOOR), dtype=np.float64)


def critical_index(tr: Trace) -> int:
    """The step that sets the risk (first maximum, in the log domain)."""
    return int(np.argmax(log10_risk_profile(tr)))


class Metric:
    """One metric; subclasses set ``name``, ``unit``, ``better``, ``description`` and
    implement ``compute_batch`` (the built-ins: one compiled pass, ``summary``) or
    ``compute`` (one trace; a plug-in may do that): the other follows. One scenario is a
    batch of one (``Trace.as_batch``), so a built-in metric has one implementation."""

    name: ClassVar[str]
    unit: ClassVar[str] = ""
    better: ClassVar[Literal["higher", "lower", "none"]] = "higher"
    description: ClassVar[str] = ""
    #: NaN is allowed and means "none" (written as an empty cell)
    optional: ClassVar[bool] = False

    def compute(self, tr: Trace) -> float:
        """The metric's value (finite) for one trace: its batch of one."""
        if type(self).compute_batch is Metric.compute_batch:
            raise TypeError(f"metric {self.name!r} implements neither compute nor compute_batch")
        return float(np.asarray(self.compute_batch(tr.as_batch()), dtype=np.float64)[0])

    def compute_batch(self, bt: BatchTrace) -> np.ndarray:
        """(B,) values for a batch; default: ``compute`` per row."""
        if type(self).compute is Metric.compute:
            raise TypeError(f"metric {self.name!r} implements neither compute nor compute_batch")
        return np.array([self.compute(bt.row(i)) for i in range(len(bt))], dtype=np.float64)


M = TypeVar("M", bound=type[Metric])


_METRICS: Registry[type[Metric]] = Registry("metric", key=lambda c: c.name, on_lookup=load_plugins)


#: Decimals of a time (s) in the output files: the evaluation's step is 0.05 s, and a
#: time computed as ``k * dt`` carries float noise (96 * 0.05 = 4.800000000000001).
TIME_DECIMALS = 9


def output_value(name: str, value: float) -> float | None:
    """A metric's value as written to the output files (ranking, evaluation): None (an
    empty cell) where it is undefined (NaN, inf); a time (name ending in ``_s``) rounded to
    ``TIME_DECIMALS`` (1 ns); anything else as it is."""
    if not math.isfinite(value):
        return None
    return round(value, TIME_DECIMALS) if name.endswith("_s") else value


def register_metric(cls: M) -> M:
    """Class decorator: register a metric under ``cls.name``."""
    return _METRICS.register(cls)


def metric_names() -> list[str]:
    """Registered metric names in registration order (built-ins first)."""
    return _METRICS.names(sort=False)


def get_metric(name: str) -> Metric:
    """An instance of a registered metric; KeyError names the known ones."""
    cls = _METRICS.get(name)
    if cls is None:
        raise KeyError(f"unknown metric {name!r}; known: {', '.join(metric_names())}")
    return cls()


def compute_all(tr: Trace, names: list[str] | None = None) -> dict[str, float]:
    """Every (or the named) metric of a trace."""
    out = {}
    for n in names or metric_names():
        metric = get_metric(n)
        v = float(metric.compute(tr))
        if not math.isfinite(v) and not (metric.optional and math.isnan(v)):
            raise ValueError(f"metric {n} is not finite: {v}")
        out[n] = v
    return out


def compute_all_batch(bt: BatchTrace, names: list[str] | None = None) -> dict[str, np.ndarray]:
    """Every (or the named) metric of every row of a batch."""
    out = {}
    for n in names or metric_names():
        metric = get_metric(n)
        v = np.asarray(metric.compute_batch(bt), dtype=np.float64)
        bad = ~np.isfinite(v)
        if metric.optional:
            bad &= ~np.isnan(v)
        if np.any(bad):
            raise ValueError(f"metric {n} is not finite in some row")
        out[n] = v
    return out


@dataclass(frozen=True)
class BatchSummary:
    """Every built-in metric's per-row ingredients of a batch, from one compiled pass
    (``fastmetrics.summarize``): (B,) arrays."""

    values: dict[str, np.ndarray]
    detection: np.ndarray
    corridor_start: np.ndarray
    corridor_end: np.ndarray


def summary(bt: BatchTrace) -> BatchSummary:
    """The ``BatchSummary`` of a batch (computed once, cached on the batch)."""
    hit = bt.__dict__.get("_summary")
    if isinstance(hit, BatchSummary):
        return hit
    b = len(bt)
    out = np.empty((b, len(COLUMNS)))
    idx = np.empty((b, 3), dtype=np.int64)
    rule = bt.rule
    cumulative = rule.kind == "cumulative"
    det = (
        np.zeros(b, dtype=np.int64)
        if cumulative
        else np.ascontiguousarray(bt.detection_index, dtype=np.int64)
    )
    summarize(
        np.ascontiguousarray(bt.log_miss),
        np.ascontiguousarray(bt.ttc),
        np.ascontiguousarray(bt.headway),
        np.ascontiguousarray(bt.distance),
        np.ascontiguousarray(bt.t, dtype=np.float64),
        np.ascontiguousarray(bt.n, dtype=np.int64),
        det,
        cumulative,
        float(rule.threshold),
        LEAD_IN_S,
        TAU_S,
        LOW_PD,
        LOG10_RISK_FLOOR,
        out,
        idx,
    )
    res = BatchSummary(
        {c: out[:, j] for j, c in enumerate(COLUMNS)}, idx[:, 0], idx[:, 1], idx[:, 2]
    )
    bt.__dict__["_summary"] = res
    return res


def _rows(bt: BatchTrace) -> np.ndarray:
    return np.arange(len(bt))


class _SummaryMetric(Metric):
    """A value of the compiled batch pass (``summary``), capped at ``CAP_S`` (``cap``)."""

    key: ClassVar[str] = ""
    cap: ClassVar[bool] = False

    def compute_batch(self, bt: BatchTrace) -> np.ndarray:
        v = np.asarray(summary(bt).values[self.key], dtype=np.float64)
        return np.minimum(v, CAP_S) if self.cap else v


def _declare(base: type[Metric], name: str, description: str, **attrs: object) -> None:
    """Register a metric of ``base`` (a column of the compiled pass or a field of the
    collision outcome) under ``name``: the class is only its declaration."""
    cls = type(
        "".join(w.title() for w in name.split("_")),
        (base,),
        {"name": name, "description": description, **attrs},
    )
    register_metric(cls)


def _summary_metric(
    name: str,
    key: str,
    description: str,
    unit: str = "",
    better: Literal["higher", "lower", "none"] = "higher",
    cap: bool = False,
) -> None:
    """Register a metric that is one column of the compiled batch pass."""
    _declare(_SummaryMetric, name, description, key=key, unit=unit, better=better, cap=cap)


_summary_metric("risk", "risk", "max_k P_undet(t_k) exp(-TTC_k / 2 s) (see module docstring)")
_summary_metric(
    "log10_risk",
    "log10_risk",
    "log10 of the risk, computed in the log domain: the ranking and search "
    "objective, graded even where the risk underflows (floor -300)",
)
_summary_metric(
    "p_undetected_end",
    "p_undetected_end",
    "probability the target is still undetected at the end (or at impact)",
)


@register_metric
class Detected(Metric):
    name = "detected"
    better = "lower"
    description = "1 if reliably detected (cumulative Pd >= 0.99) within the scenario"

    def compute_batch(self, bt: BatchTrace) -> np.ndarray:
        return (detection_index_batch(bt) >= 0).astype(np.float64)


@register_metric
class TimeToDetection(Metric):
    name = "t_detect_s"
    unit = "s"
    description = "time of first reliable detection (scenario duration if never)"

    def compute_batch(self, bt: BatchTrace) -> np.ndarray:
        k = detection_index_batch(bt)
        return np.where(k >= 0, bt.t[np.maximum(k, 0)], bt.duration_s)


_summary_metric(
    "ttc_at_detect_s",
    "ttc_at",
    "TTC at first reliable detection (min TTC if never detected; cap 99 s)",
    "s",
    "lower",
    cap=True,
)
_summary_metric(
    "headway_at_detect_s",
    "headway_at",
    "time headway at first reliable detection (min if never; cap 99 s)",
    "s",
    "lower",
    cap=True,
)
_summary_metric(
    "distance_at_detect_m",
    "distance_at",
    "ego rear axle to target centre at detection (min distance if never)",
    "m",
    "lower",
)
_summary_metric(
    "min_ttc_s",
    "min_ttc",
    "minimum TTC over the scenario (cap 99 s; 0 = collision)",
    "s",
    "lower",
    cap=True,
)
_summary_metric("mean_pd", "mean_pd", "mean per-step fused Pd", better="lower")


@register_metric
class CorridorDuration(Metric):
    name = "corridor_s"
    unit = "s"
    description = (
        "longest contiguous stretch with Pd < 0.5, duration (its sensor cycles, from the "
        "start of the first to the end of the last, within the scenario's time axis)"
    )

    def compute_batch(self, bt: BatchTrace) -> np.ndarray:
        a, b = corridor_batch(bt)
        # a stretch reaching the last step ends with the time axis: N steps of a 10 s axis
        # at 20 Hz (201) are 10 s, not 10.05 (hostile round nine)
        end = np.minimum(b * DT_S, float(bt.t[-1] - bt.t[0]))
        return np.asarray(np.maximum(end - a * DT_S, 0.0), dtype=np.float64)


class _CorridorPoint(Metric):
    unit = "m"
    better = "none"
    index: ClassVar[int] = 0  # 0: start, 1: end
    coord: ClassVar[str] = "x"

    def compute_batch(self, bt: BatchTrace) -> np.ndarray:
        a, b = corridor_batch(bt)
        k = a if self.index == 0 else np.maximum(b - 1, 0)
        v = (bt.x if self.coord == "x" else bt.y)[_rows(bt), k]
        return np.where(b > a, v, 0.0)


@register_metric
class CorridorT0(Metric):
    name = "corridor_t0_s"
    unit = "s"
    better = "none"
    description = "start time of the longest low-detection corridor"

    def compute_batch(self, bt: BatchTrace) -> np.ndarray:
        return np.asarray(bt.t[corridor_batch(bt)[0]], dtype=np.float64)


@register_metric
class CorridorX0(_CorridorPoint):
    name = "corridor_x0_m"
    description = "target x (ego frame) where the corridor starts"


@register_metric
class CorridorY0(_CorridorPoint):
    name = "corridor_y0_m"
    coord = "y"
    description = "target y (ego frame) where the corridor starts"


@register_metric
class CorridorX1(_CorridorPoint):
    name = "corridor_x1_m"
    index = 1
    description = "target x (ego frame) where the corridor ends"


@register_metric
class CorridorY1(_CorridorPoint):
    name = "corridor_y1_m"
    index = 1
    coord = "y"
    description = "target y (ego frame) where the corridor ends"


class _OutcomeMetric(Metric):
    """A field of the collision outcome (``search.outcome``; ``BatchTrace.outcome``)."""

    field: ClassVar[str] = ""

    def compute(self, tr: Trace) -> float:
        return float(tr.extra[self.field])

    def compute_batch(self, bt: BatchTrace) -> np.ndarray:
        return np.asarray(getattr(bt.outcome, self.field), dtype=np.float64)


def _outcome_metric(
    name: str,
    description: str,
    unit: str = "",
    better: Literal["higher", "lower", "none"] = "higher",
    optional: bool = False,
) -> None:
    """Register a metric that is a field of the collision outcome."""
    _declare(
        _OutcomeMetric, name, description, field=name, unit=unit, better=better, optional=optional
    )


_outcome_metric(
    "collision_probability",
    "probability that the vehicle confirms the target too late to avoid the "
    "collision (M-of-N confirmation, latency, jerk-limited braking)",
)

_outcome_metric("impact_speed_kmh", "expected relative impact speed given a collision", unit="km/h")

_outcome_metric(
    "collision_perfect",
    "1 if a vehicle with perfect perception (same reaction) still collides",
    better="none",
)

_outcome_metric(
    "t_safe_s",
    "latest time at which a confirmed detection still avoids the collision (empty: none does)",
    unit="s",
    better="none",
    optional=True,
)

_outcome_metric(
    "detection_margin_s",
    "t_safe minus the median confirmation time (negative: too late; empty: "
    "no t_safe or confirmation less likely than 1/2)",
    unit="s",
    better="lower",
    optional=True,
)

_outcome_metric(
    "t_confirm_median_s",
    "median time of the first confirmation (empty: P(confirmed) < 1/2, or no collision to avoid)",
    unit="s",
    optional=True,
)

_outcome_metric(
    "t_threat_s",
    "when the target becomes a threat (enters the ego's planned path corridor)",
    unit="s",
    better="none",
    optional=True,
)

_outcome_metric(
    "perfect_margin_s",
    "how much later than perfect perception (in line of sight) a confirmation "
    "may come and still avoid the collision; below one confirmation window the "
    "scenario is marginal, not a sensor weakness (empty: perfect perception "
    "collides too)",
    unit="s",
    better="none",
    optional=True,
)

_outcome_metric(
    "p_never_confirmed",
    "probability that the target is never confirmed before the end or impact "
    "(empty: no collision to avoid)",
    optional=True,
)


#: Metrics of a ranking row that are probabilities (0..1) and that are never negative.
_PROBABILITY_METRICS = frozenset(
    {
        "risk",
        "p_undetected_end",
        "detected",
        "mean_pd",
        "collision_probability",
        "collision_perfect",
        "p_never_confirmed",
        "lookup_collision_probability",
    }
)
_NON_NEGATIVE_METRICS = frozenset(
    {"impact_speed_kmh", "min_ttc_s", "distance_at_detect_m", "t_detect_s", "t_safe_s"}
)


def check_metric_value(name: str, v: Any) -> None:
    """A metric of a ranking row: null or a finite number (not text such as
    "Infinity"), within 0..1 for a probability, >= 0 for a speed, distance or time of
    ``_NON_NEGATIVE_METRICS``, <= 0 for ``log10_risk``; else ``ValueError``."""
    if v is None:
        return
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
        raise ValueError(f"expected a finite number or null, got {str(v)[:40]!r}")
    if name in _PROBABILITY_METRICS and not 0.0 <= v <= 1.0:
        raise ValueError(f"expected a probability within 0..1, got {v!r}")
    if name in _NON_NEGATIVE_METRICS and v < 0.0:
        raise ValueError(f"expected a number >= 0, got {v!r}")
    if name == "log10_risk" and v > 0.0:
        raise ValueError(f"expected a number <= 0 (a log10 probability), got {v!r}")
