"""Scenarios generated in batches: B parameter vectors -> (B, T) ego and target states.

The search evaluates tens of thousands of candidates per second, so trajectories are
generated for a whole batch at once with array operations; the single-scenario API
(``Family.generate``) is a batch of one, so both give identical trajectories.

Lane centres come from a ``LaneTable``: the exact lane-centre pose of the OpenDRIVE reader
sampled every ``LANE_TABLE_STEP_M`` along the road and linearly interpolated. The error of
the interpolation is bounded by the chord sagitta ``h^2 / (8 R)`` (0.1 m steps on a 500 m
radius: 2.5e-6 m; tested against the exact reader).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from sensorgap.roads import RoadNetwork
from sensorgap.scenarios.fastpath import (
    affine_progress,
    lane_tracks,
    path_states,
    row_bounds,
    table_poses,
    track_extremes,
)
from sensorgap.scenarios.trajectory import Limits, Trajectory, blend


@dataclass(frozen=True)
class OccluderPath:
    """A road user or object that only hides the target (issue #17): its centre's
    trajectory and its box (``label``: e.g. the target class it is sized as)."""

    label: str
    path: Trajectory
    length_m: float
    width_m: float
    height_m: float


@dataclass(frozen=True)
class Scenario:
    """Generated trajectories: ego (rear axle) and target (centre), same time axis, and
    the occluders of the scene (none: an empty road)."""

    ego: Trajectory
    target: Trajectory
    target_class: str
    occluders: tuple[OccluderPath, ...] = ()


F64 = NDArray[np.float64]
Mask = NDArray[np.bool_]

#: Sampling step of the lane tables, m.
LANE_TABLE_STEP_M = 0.1


@dataclass(frozen=True)
class Tracks:
    """World-frame states of B objects at T times: x, y (m), heading (rad, unwrapped,
    counter-clockwise from east), speed (m/s); each (B, T)."""

    x: F64
    y: F64
    heading: F64
    speed: F64
    #: (B, 3) per row: max speed, max |longitudinal| and |lateral| acceleration (the
    #: ``check_tracks`` extremes), when the generator computed them on the way
    extremes: F64 | None = None

    def row(self, t: F64, i: int) -> Trajectory:
        """Row ``i`` as a ``Trajectory``."""
        return Trajectory(
            t=t,
            x=self.x[i].copy(),
            y=self.y[i].copy(),
            heading=self.heading[i].copy(),
            speed=self.speed[i].copy(),
        )

    def take(self, rows: NDArray[np.intp]) -> Tracks:
        """The selected rows."""
        return Tracks(
            self.x[rows],
            self.y[rows],
            self.heading[rows],
            self.speed[rows],
            None if self.extremes is None else self.extremes[rows],
        )


@dataclass(frozen=True)
class OccluderTracks:
    """One occluder of every row of a batch: (B, T) centre states and its box, m."""

    label: str
    tracks: Tracks
    length_m: float
    width_m: float
    height_m: float

    def take(self, rows: NDArray[np.intp]) -> OccluderTracks:
        """The selected rows."""
        return OccluderTracks(
            self.label, self.tracks.take(rows), self.length_m, self.width_m, self.height_m
        )

    def row(self, t: F64, i: int) -> OccluderPath:
        """Row ``i`` as an ``OccluderPath``."""
        return OccluderPath(
            self.label, self.tracks.row(t, i), self.length_m, self.width_m, self.height_m
        )


@dataclass
class ScenarioBatch:
    """B generated scenarios on one time axis.

    Attributes:
        t: (T,) time, s. ego: rear-axle states. target: target-centre states.
        ok: (B,) feasible and on the road; rows with ``ok`` False hold placeholder states
            (finite, not meaningful) and ``notes[i]`` says why.
        target_class: the target class (``targets.toml``).
        occluders: road users and objects that only hide the target (issue #17).
    """

    t: F64
    ego: Tracks
    target: Tracks
    ok: Mask
    notes: list[str]
    target_class: str
    offroad: Mask | None = None
    occluders: tuple[OccluderTracks, ...] = ()
    #: the target must start beyond every confirming sensor's reach
    #: (``FamilyKind.start_out_of_reach``)
    start_out_of_reach: bool = False

    def __post_init__(self) -> None:
        if self.offroad is None:
            self.offroad = np.zeros(len(self.ok), dtype=bool)

    def __len__(self) -> int:
        return len(self.ok)

    @classmethod
    def of(cls, sc: Scenario) -> ScenarioBatch:
        """A batch of one scenario."""

        def tracks(tr: Trajectory) -> Tracks:
            return Tracks(tr.x[None, :], tr.y[None, :], tr.heading[None, :], tr.speed[None, :])

        return cls(
            sc.ego.t,
            tracks(sc.ego),
            tracks(sc.target),
            np.ones(1, dtype=bool),
            [""],
            sc.target_class,
            occluders=tuple(
                OccluderTracks(o.label, tracks(o.path), o.length_m, o.width_m, o.height_m)
                for o in sc.occluders
            ),
        )

    def reject(self, mask: Mask, note: str | list[str], offroad: bool = False) -> None:
        """Mark rows infeasible (first reason kept); ``offroad``: they leave the road."""
        new = mask & self.ok
        for i in np.flatnonzero(new):
            self.notes[i] = note if isinstance(note, str) else note[i]
        if offroad:
            assert self.offroad is not None
            self.offroad |= new
        self.ok &= ~mask

    def scenario(self, i: int) -> Scenario:
        """Row ``i`` as a ``Scenario``."""
        return Scenario(
            self.ego.row(self.t, i),
            self.target.row(self.t, i),
            self.target_class,
            tuple(o.row(self.t, i) for o in self.occluders),
        )


class LaneTable:
    """Lane-centre poses of one lane sampled along its road (see module docstring)."""

    def __init__(
        self, net: RoadNetwork, road_id: str, lane: int, step_m: float = LANE_TABLE_STEP_M
    ) -> None:
        self.length = float(net.road(road_id).length)
        n = max(2, math.ceil(self.length / step_m) + 1)
        self.s = np.linspace(0.0, self.length, n)
        self.step = self.length / (n - 1)
        x, y, h, _ = net.lane_center(road_id, lane, self.s)
        self.x, self.y, self.h = x, y, np.unwrap(h)

    def tracks(self, s: F64, travel: int, t: F64) -> Tracks:
        """Tracks of objects that follow the lane (never backwards) at (B, T) road ``s``
        (m) on the uniform time axis ``t`` (s), in one compiled pass
        (``fastpath.lane_tracks``): positions as ``poses``; heading the lane's in the
        travel direction; speed by central differences as ``tracks_from_path``; and the
        feasibility extremes. (The heading ``tracks_from_path`` derives from the sampled
        positions is a chord's: on the benchmark's motorway curve within 1e-4 rad of the
        lane's inside, up to 1.8e-3 rad at the two ends, where one-sided differences lag
        by half a step's turn; deriving it costs an ``atan2`` per step, about a tenth of a
        lookup.)"""
        sc = np.ascontiguousarray(s, dtype=np.float64)
        b, n_t = sc.shape
        x, y, h, v = (np.empty((b, n_t)) for _ in range(4))
        ext = np.empty((b, 3))
        lane_tracks(
            sc,
            self.step,
            len(self.s),
            self.x,
            self.y,
            self.h,
            math.pi if travel < 0 else 0.0,
            float(t[1] - t[0]),
            x,
            y,
            h,
            v,
            ext,
        )
        return Tracks(x, y, h, v, ext)

    def poses(self, s: F64, travel: int) -> tuple[F64, F64, F64]:
        """x, y (m) and heading in the travel direction (rad) at road ``s`` (m, any
        shape; clipped to the road)."""
        flat = np.ascontiguousarray(s, dtype=np.float64).reshape(-1)
        x, y, h = np.empty(flat.size), np.empty(flat.size), np.empty(flat.size)
        table_poses(flat, self.step, len(self.s), self.x, self.y, self.h, x, y, h)
        if travel < 0:
            h += math.pi
        shape = np.shape(s)
        return x.reshape(shape), y.reshape(shape), h.reshape(shape)


def blend_batch(shapes: NDArray[np.str_], u: F64) -> F64:
    """Row-wise ``blend``: (B,) shape names, (B, T) u -> (B, T) weights."""
    out = np.empty(u.shape)
    for shape in np.unique(shapes):
        rows = shapes == shape
        out[rows] = blend(str(shape), u[rows])
    return out


def tracks_from_path(t: F64, x: F64, y: F64, fallback_heading: F64) -> Tracks:
    """Heading and speed from (B, T) sampled paths (m) at the uniform times ``t`` (s), by
    central differences; where an object stands still its heading is the fallback's (see
    ``fastpath.path_states``)."""
    x = np.ascontiguousarray(x, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    fb = np.ascontiguousarray(np.broadcast_to(fallback_heading, x.shape), dtype=np.float64)
    heading, speed = np.empty(x.shape), np.empty(x.shape)
    path_states(x, y, fb, float(t[1] - t[0]), heading, speed)
    return Tracks(x, y, heading, speed)


def check_tracks(tr: Tracks, t: F64, limits: Limits, who: str) -> tuple[Mask, list[str]]:
    """Batched ``Trajectory.check``: (B,) bound exceeded, and the reason per row (1 %
    slack, same order and wording as the single check)."""
    ext = tr.extremes
    if ext is None:
        ext = np.empty((len(tr.speed), 3))
        track_extremes(tr.heading, tr.speed, float(t[1] - t[0]), ext)
    vmax, long_acc, lat_acc = ext[:, 0], ext[:, 1], ext[:, 2]
    bad = np.zeros(len(vmax), dtype=bool)
    notes = [""] * len(vmax)
    for what, value, bound, unit in (
        ("speed", vmax, limits.max_speed, "m/s"),
        ("longitudinal acceleration", long_acc, limits.max_long_accel, "m/s2"),
        ("lateral acceleration", lat_acc, limits.max_lat_accel, "m/s2"),
    ):
        over = (value > bound * 1.01 + 1e-9) & ~bad
        for i in np.flatnonzero(over):
            notes[i] = f"{who}: {what} {value[i]:.2f} {unit} exceeds {bound:g}"
        bad |= over
    return bad, notes


def lane_progress(s0: F64, travel: int, offset: F64 | float, speed: F64, t: F64) -> F64:
    """(B, T) road s (m) of objects moving at constant ``speed`` (m/s, (B,) or (B, 1))
    along a lane in its ``travel`` direction (+1 / -1) from ``s0 + travel * offset`` (m),
    at times ``t`` (s): ``s0 + travel * (offset + speed t)`` in one compiled pass
    (``fastpath.affine_progress``), the same values as that numpy expression."""
    b = np.size(s0)

    def col(a: F64 | float) -> F64:
        return np.ascontiguousarray(
            np.broadcast_to(np.asarray(a, dtype=np.float64).reshape(-1), (b,))
        )

    out = np.empty((b, len(t)))
    affine_progress(
        col(s0),
        float(travel),
        col(offset),
        col(speed),
        np.ascontiguousarray(t, dtype=np.float64),
        out,
    )
    return out


def off_road(s: F64, length: float, road_id: str, who: str) -> tuple[Mask, list[str]]:
    """(B,) rows whose s (B, T) leaves [0, length] (m), with the reason."""
    sc = np.ascontiguousarray(s, dtype=np.float64).reshape(len(s), -1)
    lo, hi = np.empty(len(sc)), np.empty(len(sc))
    row_bounds(sc, lo, hi)
    bad = (lo < 0.0) | (hi > length)
    notes = [""] * len(lo)
    for i in np.flatnonzero(bad):
        notes[i] = (
            f"{who} leaves road {road_id} (s from {lo[i]:.1f} to {hi[i]:.1f} m, "
            f"road is 0..{length:g} m)"
        )
    return bad, notes
