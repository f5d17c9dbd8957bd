"""Which encounters the search may use (issue #13, "only possible encounters"): the bodies
do not overlap at t = 0, the first open-loop contact is with the ego's front (a target
does not move into the ego's side or rear), and the encounter starts non-critical (TTC at
t = 0 at least ``START_TTC_S``). The search stores the others as infeasible with a note
(``problem.SearchProblem``) and does not look their detection up (``evaluate``)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from sensorgap.search.outcome import Encounter

F64 = NDArray[np.float64]

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


def possible(
    enc: Encounter, x: F64, psi: F64 | None, x_front: float, length: float, width: float
) -> NDArray[np.bool_]:
    """(B,) whether each encounter is one the search may use (module docstring; arguments
    as ``encounter_problems``)."""
    ok = enc.ttc_path[:, 0] >= START_TTC_S
    rows, _, _, at_start, side = _contacts(enc, x, psi, x_front, length, width)
    ok[rows[at_start | side]] = False
    return np.asarray(ok)


def encounter_problems(
    enc: Encounter,
    t: F64,
    x: F64,
    psi: F64 | None,
    x_front: float,
    length: float,
    width: float,
) -> list[tuple[int, str]]:
    """(row, note) of every encounter the search may not use: the impossible ones (bodies
    overlapping at t = 0, a first contact not with the ego's front), then those that start
    critical. ``t``: the time axis, s; ``x``, ``psi``: (B, T) target centre ahead of the
    ego's rear axle, m, and relative heading, rad; ``x_front``: the ego's front bumper, m;
    target ``length`` and ``width``, m."""
    out: list[tuple[int, str]] = []
    rows, k, xc, at_start, side = _contacts(enc, x, psi, x_front, length, width)
    for j, kk, x0, st, sd in zip(
        rows.tolist(), k.tolist(), xc.tolist(), at_start.tolist(), side.tolist(), strict=True
    ):
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
    return out
