"""Which encounters the search may use (issue #13, "only possible encounters"): the bodies
do not overlap at t = 0, the first open-loop contact is with the ego's front (a target
does not move into the ego's side or rear), no occluder (a parked car, a lead car)
overlaps the ego's body at any step, the encounter starts non-critical (TTC at t = 0 at
least ``START_TTC_S``), and, for kinds whose history before t = 0 continues their start
(``FamilyKind.start_out_of_reach``: a slower car ahead, both at constant speed), the target
starts beyond every confirming sensor's reach (``in_reach``): the detection history begins
at t = 0, so a target already within reach there would have had chances to be confirmed
that the encounter leaves out, and its collision probability would be overstated. The
search stores the others as infeasible with a note (``problem.SearchProblem``) and does
not look their detection up (``evaluate``)."""

from __future__ import annotations

import re
from collections import Counter
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgap.search.outcome import Encounter

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class StartReach:
    """Which confirming sensor has the target within reach at t = 0 (``in_reach``).

    Attributes:
        sensor: (B,) index into ``ids``, -1 for none.
        distance_m: (B,) its horizontal distance to the target's body, m (inf for none).
        ids: the confirming sensors' ids. reach_m: their ``max_range``, m.
        target: the target class, for the note.
    """

    sensor: NDArray[np.int64]
    distance_m: F64
    ids: tuple[str, ...]
    reach_m: tuple[float, ...]
    target: str = "target"

    def note(self, j: int) -> str:
        """Why row ``j`` is not used, in words."""
        i = int(self.sensor[j])
        return (
            f"starts within reach: the {self.target} is {self.distance_m[j]:.1f} m from "
            f"{self.ids[i]} (reach {self.reach_m[i]:g} m) at t = 0, where the simulated "
            "detection history begins"
        )


#: A candidate must start non-critical: TTC at t = 0 at least this, s (about twice the
#: risk's time constant). An encounter that begins at a smaller TTC measures its initial
#: condition (a target placed close in front), not what the sensors saw while it developed.
START_TTC_S = 4.0

#: One step before the first open-loop contact the target's rear-most point must be ahead
#: of the ego's front bumper less this tolerance, m (estimate: angled front-corner
#: contacts); otherwise the target moved into the ego's side or rear, an impossible
#: encounter for this search. (The step before: at the contact step itself a rear-end
#: overlaps by up to the closing distance of one step, 0.75 m at 15 m/s and 20 Hz.)
CONTACT_TOLERANCE_M = 0.5


def _contacts(
    enc: Encounter, x: F64, psi: F64 | None, x_front: float, length: float, width: float
) -> tuple[NDArray[np.intp], NDArray[np.int64], F64, NDArray[np.bool_], NDArray[np.bool_]]:
    """The rows with an open-loop contact, its step, the target's ego-frame x (m) the step
    before, and whether the bodies overlap at t = 0 or the contact is not with the ego's
    front (``x``, ``psi``: (B, T) target centre ahead of the rear axle, m, and relative
    heading, rad; ``x_front``: the ego's front bumper, m; target ``length``, ``width``, m)."""
    rows = np.flatnonzero(enc.collide_step >= 0)
    k = enc.collide_step[rows]
    at_start = k == 0
    kb = np.maximum(k - 1, 0)  # the step before the contact
    p = np.zeros(rows.size) if psi is None else psi[rows, kb]
    xc = x[rows, kb]
    x_min = xc - 0.5 * (np.abs(np.cos(p)) * length + np.abs(np.sin(p)) * width)
    side = ~at_start & (x_min < x_front - CONTACT_TOLERANCE_M)
    return rows, k, xc, at_start, side


def occluder_contact(
    boxes: F64 | None, n: NDArray[np.int64], x_front: float, x_rear: float, width: float
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """(B,) the first step at which an occluder's box overlaps the ego's body, -1 for none,
    and (B,) which occluder (its index). ``boxes``: (B, T, M, 7) occluder boxes in the ego
    frame (``coverage.occluders.COLUMNS``: centre x, y, cos and sin of the heading, half
    length, half width, height; m); ``n``: steps per row; the ego's body from ``x_rear`` to
    ``x_front`` (m, ahead of the rear axle), ``width`` wide. Two rectangles overlap unless
    one of their four edge directions separates them (separating axis theorem)."""
    if boxes is None or boxes.shape[2] == 0:
        none = np.full(len(n), -1, dtype=np.int64)
        return none, none.copy()
    ahl, ahw, ax = 0.5 * (x_front - x_rear), 0.5 * width, 0.5 * (x_front + x_rear)
    dx, dy = boxes[..., 0] - ax, boxes[..., 1]
    c, s = np.abs(boxes[..., 2]), np.abs(boxes[..., 3])
    hl, hw = boxes[..., 4], boxes[..., 5]
    apart = (
        (np.abs(dx) > ahl + c * hl + s * hw)
        | (np.abs(dy) > ahw + s * hl + c * hw)
        | (np.abs(dx * boxes[..., 2] + dy * boxes[..., 3]) > hl + ahl * c + ahw * s)
        | (np.abs(-dx * boxes[..., 3] + dy * boxes[..., 2]) > hw + ahl * s + ahw * c)
    )
    valid = np.arange(boxes.shape[1])[None, :, None] < n[:, None, None]
    hit: NDArray[np.bool_] = np.asarray(~apart & valid)  # (B, T, M)
    any_t = np.any(hit, axis=2)
    step = np.where(any_t.any(axis=1), np.argmax(any_t, axis=1), -1).astype(np.int64)
    which = np.argmax(hit[np.arange(len(n)), np.maximum(step, 0)], axis=1).astype(np.int64)
    return step, np.where(step >= 0, which, -1)


def in_reach(
    x: F64,
    y: F64,
    psi: F64,
    length: float,
    width: float,
    mounts: Sequence[tuple[float, float, float]],
    counts: NDArray[np.bool_] | None = None,
) -> tuple[NDArray[np.int64], F64]:
    """(B,) which of ``mounts`` (sensor position x, y in the ego frame, m, and its
    ``max_range``, m) has the target's body within reach at t = 0, -1 for none (the one
    it is deepest within: largest reach minus distance), and (B,) that sensor's distance
    to the body, m (inf for none). ``x``, ``y``, ``psi``: (B,) the target centre in the
    ego frame, m, and its relative heading, rad; ``length``, ``width``: its body, m;
    ``counts``: (B, M) whether mount m counts for row b (None: every mount, every row).

    The distance is the horizontal one from the sensor to the nearest point of the body's
    box: never more than the 3-D range, so a body beyond it is beyond every sensor's
    ``max_range`` (Pd = 0 there, paper Sec. III) whatever the weather, sun or height."""
    b = len(x)
    which = np.full(b, -1, dtype=np.int64)
    dist = np.full(b, np.inf)
    best = np.zeros(b)  # how deep within reach, m
    c, s = np.cos(psi), np.sin(psi)
    for i, (mx, my, reach) in enumerate(mounts):
        dx, dy = mx - x, my - y
        u = np.abs(c * dx + s * dy) - 0.5 * length  # along the body, beyond its half length
        v = np.abs(-s * dx + c * dy) - 0.5 * width
        d = np.hypot(np.maximum(u, 0.0), np.maximum(v, 0.0))
        deeper = (d <= reach) & ((which < 0) | (reach - d > best))
        if counts is not None:
            deeper &= counts[:, i]
        which[deeper] = i
        dist[deeper] = d[deeper]
        best[deeper] = reach - d[deeper]
    return which, dist


def possible(
    enc: Encounter,
    x: F64,
    psi: F64 | None,
    x_front: float,
    length: float,
    width: float,
    occluder_step: NDArray[np.int64] | None = None,
    reach_sensor: NDArray[np.int64] | None = None,
) -> NDArray[np.bool_]:
    """(B,) whether each encounter is one the search may use (module docstring; arguments
    as ``encounter_problems``; ``reach_sensor``: ``in_reach``'s first value, None where
    the kind does not ask the target to start out of reach)."""
    ok = enc.ttc_path[:, 0] >= START_TTC_S
    rows, _, _, at_start, side = _contacts(enc, x, psi, x_front, length, width)
    ok[rows[at_start | side]] = False
    if occluder_step is not None:
        ok &= occluder_step < 0
    if reach_sensor is not None:
        ok &= reach_sensor < 0
    return np.asarray(ok)


def encounter_problems(
    enc: Encounter,
    t: F64,
    x: F64,
    psi: F64 | None,
    x_front: float,
    length: float,
    width: float,
    occluders: tuple[NDArray[np.int64], NDArray[np.int64], tuple[str, ...]] | None = None,
    reach: StartReach | None = None,
) -> list[tuple[int, str]]:
    """(row, note) of every encounter the search may not use: the impossible ones (an
    occluder overlapping the ego's body at some step, bodies overlapping at t = 0, a first
    contact not with the ego's front), then those that start critical. ``t``: the time
    axis, s; ``x``, ``psi``: (B, T) target centre ahead of the ego's rear axle, m, and
    relative heading, rad; ``x_front``: the ego's front bumper, m; target ``length`` and
    ``width``, m; ``occluders``: ``occluder_contact``'s (step, occluder) and the labels;
    ``reach``: which confirming sensor has the target within reach at t = 0 (``in_reach``),
    None where the kind does not ask the target to start out of reach."""
    out: list[tuple[int, str]] = []
    if occluders is not None:
        step, which, labels = occluders
        for j in np.flatnonzero(step >= 0).tolist():
            label = labels[which[j]] if 0 <= which[j] < len(labels) else "an occluder"
            out.append(
                (
                    j,
                    f"impossible encounter: the {label} overlaps the ego's body at "
                    f"t = {t[step[j]]:.2f} s",
                )
            )
    rows, k, xc, at_start, side = _contacts(enc, x, psi, x_front, length, width)
    marked = {j for j, _ in out}
    for j, kk, x0, st, sd in zip(
        rows.tolist(), k.tolist(), xc.tolist(), at_start.tolist(), side.tolist(), strict=True
    ):
        if j in marked:
            continue
        if st:
            out.append((j, "impossible encounter: the bodies overlap at t = 0"))
        elif sd:
            where = "side" if x0 > 0.0 else "rear"
            out.append(
                (
                    j,
                    f"impossible encounter: the target moves into the ego's "
                    f"{where} at t = {t[kk]:.2f} s (first contact not with "
                    "the ego's front)",
                )
            )
    marked = {j for j, _ in out}
    ttc0 = enc.ttc_path[:, 0]
    out += [
        (int(j), f"starts critical: TTC {ttc0[j]:.2f} s at t = 0 (at least {START_TTC_S:g} s)")
        for j in np.flatnonzero(ttc0 < START_TTC_S)
        if int(j) not in marked
    ]
    if reach is not None:
        marked = {j for j, _ in out}
        out += [
            (j, reach.note(j))
            for j in np.flatnonzero(reach.sensor >= 0).tolist()
            if j not in marked
        ]
    return out


# --- why candidates were infeasible (summary.json, the printed line, the report) ---------

#: summary.json's ``infeasible_reasons`` names at most this many kinds (the most frequent;
#: the rest are counted as ``other``).
MAX_INFEASIBLE_KINDS = 10
#: A kind (a note with its numbers left out) is cut to this many characters.
MAX_KIND_CHARS = 200

#: A number standing alone in a note (not part of a name such as ``fog49`` or ``3(1)``).
_NUMBER = re.compile(r"(?<![\w(])-?\d+(?:\.\d+)?(?![\w(])")
_SPEED = " above the lawful speed in "


def infeasible_kind(note: str) -> str:
    """The kind of an infeasibility note: the note with the candidate's own numbers left
    out (``#``), so notes of one cause count together; the lawful speed note keeps its
    rule whole (its numbers are the environment's, not the candidate's)."""
    head, sep, rule = note.partition(_SPEED)
    if sep and head.startswith("ego speed "):
        kind = "ego speed" + _SPEED + rule
    else:
        kind = _NUMBER.sub("#", note) or "no note"
    return kind if len(kind) <= MAX_KIND_CHARS else kind[: MAX_KIND_CHARS - 3] + "..."


def infeasible_reasons(notes: Iterable[str]) -> dict[str, int]:
    """How many infeasible candidates each kind of note has (``infeasible_kind``), the
    most frequent first (ties by name), at most ``MAX_INFEASIBLE_KINDS`` and ``other``."""
    counts = Counter(infeasible_kind(n) for n in notes)
    ranked = sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))
    out = dict(ranked[:MAX_INFEASIBLE_KINDS])
    rest = sum(n for _, n in ranked[MAX_INFEASIBLE_KINDS:])
    if rest:
        out["other"] = out.get("other", 0) + rest
    return out


def no_feasible_note(candidates: int, reasons: dict[str, int]) -> str:
    """What a search none of whose ``candidates`` was feasible found, in words: nothing
    could be ranked because no lawful, possible encounter exists in the searched conditions
    (not because the sensors saw every target), with the counts of ``reasons``."""
    # the most frequent first, "other" last, whatever order the dict came in (summary.json
    # holds it with its keys sorted: the report listed the kinds alphabetically)
    ordered = sorted(reasons.items(), key=lambda kv: (kv[0] == "other", -kv[1], kv[0]))
    why = "; ".join(f"{n:,} {kind}" for kind, n in ordered)
    return (
        f"no feasible candidate: every one of the {candidates:,} candidates was infeasible"
        + (f" ({why})" if why else "")
        + "; nothing could be ranked, which says nothing about the sensors (no lawful, "
        "possible encounter of these families in these environments)"
    )
