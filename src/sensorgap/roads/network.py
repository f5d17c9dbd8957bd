"""``RoadNetwork``: lane graph and road <-> world coordinate transforms.

Frames and signs (OpenDRIVE): world = inertial frame, x east, y north (m), headings in rad
counter-clockwise from x. Road frame: ``s`` along the reference line (m, 0 at the road
start), ``t`` lateral (m, positive to the left of the reference line when looking along +s).
The centre lane (id 0) runs at ``t = laneOffset(s)``; left lanes (ids 1, 2, ...) stack
towards +t, right lanes (ids -1, -2, ...) towards -t, each ``width(s)`` wide.

Travel direction: with right-hand traffic (``rule="RHT"``, the default) right lanes travel
along +s and left lanes along -s (``LHT`` and a lane's ``direction="reversed"`` flip this).
The lane graph's successor/predecessor and left/right edges follow the travel direction.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cached_property
from itertools import chain
from typing import Any, overload

import networkx as nx
import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.spatial import cKDTree

from sensorgap.errors import InputError
from sensorgap.roads.geometry import Pose
from sensorgap.roads.model import ContactPoint, Junction, Lane, LaneSection, Road, eval_pieces

F64 = NDArray[np.float64]
#: A lane-graph node: (road id, lane-section index, lane id).
LaneKey = tuple[str, int, int]
#: Array input: a numpy array or a sequence of numbers.
Values = NDArray[Any] | Sequence[float]

#: How far s may overshoot [0, length] before it is an error, m.
S_TOLERANCE = 1e-6
#: Reference-line sample spacing of the world -> road search index, m.
SAMPLE_STEP = 1.0
#: A projection counts as perpendicular when the along-track residual is below this, m.
_PERP_TOL = 1e-6


@dataclass(frozen=True)
class _SampleIndex:
    """Reference-line samples of all roads in one KD-tree."""

    roads: tuple[Road, ...]
    road_of: NDArray[np.intp]  # sample -> index into roads
    s: F64  # sample -> road s, m
    reach: F64  # road index -> largest |t| of its lanes + SAMPLE_STEP, m
    tree: cKDTree


def _travel(road: Road, lane: Lane) -> int:
    """+1 if traffic on ``lane`` moves along +s, -1 if along -s."""
    sign = 1 if lane.id < 0 else -1
    if road.rule == "LHT":
        sign = -sign
    if lane.direction == "reversed":
        sign = -sign
    return sign


class RoadNetwork:
    """Roads and junctions of one OpenDRIVE file with geometry queries and a lane graph.

    Args:
        roads: road id -> ``Road``.
        junctions: junction id -> ``Junction``.
        source: name used in ``InputError`` messages (the file path).
    """

    def __init__(
        self, roads: Mapping[str, Road], junctions: Mapping[str, Junction], source: str = "<memory>"
    ) -> None:
        self.roads: dict[str, Road] = dict(roads)
        self.junctions: dict[str, Junction] = dict(junctions)
        self.source = str(source)
        self._starts = {rid: np.array([g.s for g in r.geometries]) for rid, r in roads.items()}

    # -- look-ups ----------------------------------------------------------------------
    def road(self, road_id: str | int) -> Road:
        """The road with ``road_id``; ``InputError`` if there is none."""
        rid = str(road_id)
        road = self.roads.get(rid)
        if road is None:
            known = ", ".join(list(self.roads)[:12]) + (", ..." if len(self.roads) > 12 else "")
            raise InputError(
                self.source, f"road[id={rid}]", f"road does not exist (roads: {known})"
            )
        return road

    def lane_exists(self, road_id: str | int, lane_id: int, s: float | None = None) -> bool:
        """Whether road ``road_id`` has lane ``lane_id`` (not the centre lane 0) in any lane
        section, or in the section at ``s`` (m) if given."""
        road = self.roads.get(str(road_id))
        if road is None or lane_id == 0:
            return False
        if s is None:
            return any(sec.lane(lane_id) is not None for sec in road.sections)
        if not (math.isfinite(s) and -S_TOLERANCE <= s <= road.length + S_TOLERANCE):
            return False
        return road.sections[int(road.section_index(s))].lane(lane_id) is not None

    def lane_travel(self, road_id: str | int, lane_id: int, s: float) -> int:
        """+1 if traffic on lane ``lane_id`` of road ``road_id`` at ``s`` (m) moves along
        +s, -1 if along -s (right lanes along +s; ``LHT`` and ``direction="reversed"`` flip
        it). ``InputError`` if the lane does not exist there."""
        road = self.road(road_id)
        ss = float(self._s(road, s)[0])
        idx = int(road.section_index(ss))
        lane = self._section_or_fail(road, idx, lane_id, ss).lane(lane_id)
        assert lane is not None
        return _travel(road, lane)

    def _s(self, road: Road, s: ArrayLike) -> F64:
        arr = np.atleast_1d(np.asarray(s, dtype=np.float64)).ravel()
        bad = ~np.isfinite(arr) | (arr < -S_TOLERANCE) | (arr > road.length + S_TOLERANCE)
        if np.any(bad):
            v = arr[np.flatnonzero(bad)[0]]
            raise InputError(
                self.source,
                f"road[id={road.id}]",
                f"s must be within [0, {road.length:g}] m, got {v}",
            )
        return np.clip(arr, 0.0, road.length)

    # -- reference line ----------------------------------------------------------------
    def _reference(self, road: Road, s: F64) -> tuple[F64, F64, F64, F64, F64]:
        """x, y (m), heading (rad), curvature (1/m), d(curvature)/ds (1/m^2) at road s (1-d)."""
        starts = self._starts[road.id]
        idx = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, starts.size - 1)
        out = [np.empty_like(s) for _ in range(5)]
        for i in np.unique(idx):
            m = idx == i
            g = road.geometries[int(i)]
            ds = s[m] - g.s
            x, y, h, k = g.evaluate(ds)
            for o, v in zip(out, (x, y, h, k, g.curvature_rate(ds)), strict=True):
                o[m] = v
        return out[0], out[1], out[2], out[3], out[4]

    @overload
    def reference_line(self, road_id: str | int, s: float) -> tuple[float, float, float]: ...
    @overload
    def reference_line(self, road_id: str | int, s: Values) -> tuple[F64, F64, F64]: ...

    def reference_line(self, road_id: str | int, s: ArrayLike) -> tuple[Any, Any, Any]:
        """Reference-line point x, y (m) and heading (rad) at road ``s`` (m).

        Scalars in, floats out; arrays in, arrays (same shape) out.
        """
        road = self.road(road_id)
        shape = np.shape(s)
        x, y, h, _, _ = self._reference(road, self._s(road, s))
        if not shape:
            return float(x[0]), float(y[0]), float(h[0])
        return x.reshape(shape), y.reshape(shape), h.reshape(shape)

    # -- lanes -------------------------------------------------------------------------
    def _section_or_fail(self, road: Road, idx: int, lane_id: int, s: float) -> LaneSection:
        sec = road.sections[idx]
        if sec.lane(lane_id) is None:
            ids = ", ".join(map(str, sec.lane_ids))
            raise InputError(
                self.source,
                f"road[id={road.id}]/lane[id={lane_id}]",
                f"lane does not exist at s={s:g} m (laneSection[{idx}] has lanes {ids})",
            )
        return sec

    def _lane_t(self, road: Road, lane_id: int, s: F64) -> tuple[F64, F64, F64, F64, F64]:
        """Inner and outer border t (m) of the lane and its centre t, dt/ds, d2t/ds2."""
        off, doff, ddoff = eval_pieces(road.lane_offsets, s)
        inner, outer = off.copy(), off.copy()
        tc, dtc, ddtc = off.copy(), doff.copy(), ddoff.copy()
        secs = road.section_index(s)
        sign = 1.0 if lane_id > 0 else -1.0
        for i in np.unique(secs):
            m = secs == i
            sec = self._section_or_fail(road, int(i), lane_id, float(s[m][0]))
            if lane_id == 0:
                continue
            ds = s[m] - sec.s
            cum = [np.zeros(ds.shape) for _ in range(3)]
            side = sec.left if lane_id > 0 else sec.right
            for lane in side[: abs(lane_id) - 1]:
                for c, v in zip(cum, eval_pieces(lane.widths, ds), strict=True):
                    c += v
            w, dw, ddw = eval_pieces(side[abs(lane_id) - 1].widths, ds)
            inner[m] = off[m] + sign * cum[0]
            outer[m] = off[m] + sign * (cum[0] + w)
            tc[m] = off[m] + sign * (cum[0] + 0.5 * w)
            dtc[m] = doff[m] + sign * (cum[1] + 0.5 * dw)
            ddtc[m] = ddoff[m] + sign * (cum[2] + 0.5 * ddw)
        return inner, outer, tc, dtc, ddtc

    def lane_width(self, road_id: str | int, lane_id: int, s: ArrayLike) -> F64:
        """Width (m) of lane ``lane_id`` at road ``s`` (m, array); 0 for the centre lane."""
        road = self.road(road_id)
        ss = self._s(road, s)
        inner, outer, _, _, _ = self._lane_t(road, lane_id, ss)
        return np.abs(outer - inner).reshape(np.shape(s))

    def lane_edges(self, road_id: str | int, lane_id: int, s: ArrayLike) -> tuple[F64, F64]:
        """Lateral position t (m) of the inner (towards the centre lane) and outer border of
        lane ``lane_id`` at road ``s`` (m, array)."""
        road = self.road(road_id)
        ss = self._s(road, s)
        inner, outer, _, _, _ = self._lane_t(road, lane_id, ss)
        return inner.reshape(np.shape(s)), outer.reshape(np.shape(s))

    def lane_center(self, road_id: str | int, lane_id: int, s: ArrayLike) -> Pose:
        """Centre line of lane ``lane_id`` at road ``s`` (m, array).

        The centre lies at ``t = laneOffset(s) +/- (widths of the inner lanes + width / 2)``
        (+ for left lanes, - for right lanes; lane 0 gives the laneOffset line). Returns
        x, y (m), heading (rad, along +s) and curvature (1/m, positive = left) of that offset
        curve. ``InputError`` if the lane does not exist at some ``s``.
        """
        road = self.road(road_id)
        ss = self._s(road, s)
        x, y, h, k, dk = self._reference(road, ss)
        _, _, t, dt, ddt = self._lane_t(road, lane_id, ss)
        sh, ch = np.sin(h), np.cos(h)
        px, py = x - t * sh, y + t * ch
        # Derivatives of P = R + t N in the (T, N) frame of the reference line.
        a1, a2 = 1.0 - t * k, dt
        b1, b2 = -2.0 * dt * k - t * dk, (1.0 - t * k) * k + ddt
        speed2 = a1 * a1 + a2 * a2
        curv = np.divide(
            a1 * b2 - a2 * b1, speed2**1.5, out=np.zeros_like(speed2), where=speed2 > 0.0
        )
        heading = h + np.arctan2(a2, a1)
        shape = np.shape(s)
        return px.reshape(shape), py.reshape(shape), heading.reshape(shape), curv.reshape(shape)

    # -- road <-> world ----------------------------------------------------------------
    @overload
    def road_to_world(self, road_id: str | int, s: float, t: float) -> tuple[float, float]: ...
    @overload
    def road_to_world(
        self, road_id: str | int, s: Values, t: Values | float
    ) -> tuple[F64, F64]: ...

    def road_to_world(self, road_id: str | int, s: ArrayLike, t: ArrayLike) -> tuple[Any, Any]:
        """World x, y (m) of road coordinates ``s`` (m) and ``t`` (m, left positive)."""
        road = self.road(road_id)
        sb, tb = np.broadcast_arrays(
            np.asarray(s, dtype=np.float64), np.asarray(t, dtype=np.float64)
        )
        if not np.all(np.isfinite(tb)):
            raise InputError(self.source, f"road[id={road.id}]", "t must be finite")
        x, y, h, _, _ = self._reference(road, self._s(road, sb))
        tt = tb.ravel()
        wx, wy = x - tt * np.sin(h), y + tt * np.cos(h)
        if not sb.shape:
            return float(wx[0]), float(wy[0])
        return wx.reshape(sb.shape), wy.reshape(sb.shape)

    def road_extents(self, road_id: str | int, s: ArrayLike) -> tuple[F64, F64]:
        """Lateral position t (m) of the outer border of the leftmost and of the rightmost
        lane of road ``road_id`` at ``s`` (m, array)."""
        road = self.road(road_id)
        left, right = road.extents(self._s(road, s))
        return left.reshape(np.shape(s)), right.reshape(np.shape(s))

    def off_road_m(self, x: ArrayLike, y: ArrayLike) -> F64:
        """Distance (m) of world points outside the lanes of the road they project onto
        (0 for points on a lane): how far a trajectory leaves the road."""
        rid, lane, s, t = self.world_to_road(np.atleast_1d(x), np.atleast_1d(y))
        out = np.zeros(len(s))
        for i in np.flatnonzero(np.asarray(lane) == 0):
            road = self.road(str(rid[i]))
            left, right = road.extents(np.array([s[i]]))
            out[i] = max(float(t[i] - left[0]), float(right[0] - t[i]), 0.0)
        return out

    def lane_at(self, road_id: str | int, s: ArrayLike, t: ArrayLike) -> NDArray[np.int64]:
        """Lane id containing road point (s, t) (m); 0 where the point is outside all lanes.

        Borders belong to the lane farther out; a point exactly on the centre lane belongs to
        lane 1 (or -1 if the section has no left lanes).
        """
        road = self.road(road_id)
        sb, tb = np.broadcast_arrays(
            np.asarray(s, dtype=np.float64), np.asarray(t, dtype=np.float64)
        )
        return self._lane_at(road, self._s(road, sb), tb.ravel()).reshape(sb.shape)

    def _lane_at(self, road: Road, s: F64, t: F64) -> NDArray[np.int64]:
        tau = t - eval_pieces(road.lane_offsets, s)[0]
        out = np.zeros(s.shape, dtype=np.int64)
        secs = road.section_index(s)
        for i in np.unique(secs):
            m = np.flatnonzero(secs == i)
            sec = road.sections[int(i)]
            ds = s[m] - sec.s
            res = np.zeros(m.size, dtype=np.int64)
            for lanes, sign in ((sec.left, 1), (sec.right, -1)):
                if not lanes:
                    continue
                cum = np.cumsum(np.maximum(np.stack([ln.width(ds) for ln in lanes]), 0.0), axis=0)
                a = sign * tau[m]
                inside = (a >= 0.0) & (a < cum[-1]) & (res == 0)
                k = np.sum(a[None, :] >= cum, axis=0)
                res = np.where(inside, sign * (k + 1), res)
            out[m] = res
        return out

    @cached_property
    def _index(self) -> _SampleIndex:
        roads = tuple(self.roads.values())
        xs, ys, ss, owner, reach = [], [], [], [], []
        for i, road in enumerate(roads):
            n = max(2, math.ceil(road.length / SAMPLE_STEP) + 1)
            s = np.linspace(0.0, road.length, n)
            x, y, _, _, _ = self._reference(road, s)
            left, right = road.extents(s)
            xs.append(x)
            ys.append(y)
            ss.append(s)
            owner.append(np.full(n, i, dtype=np.intp))
            reach.append(float(max(np.max(np.abs(left)), np.max(np.abs(right)))) + SAMPLE_STEP)
        tree = cKDTree(np.column_stack([np.concatenate(xs), np.concatenate(ys)]))
        return _SampleIndex(roads, np.concatenate(owner), np.concatenate(ss), np.array(reach), tree)

    def _candidates(self, px: F64, py: F64) -> tuple[NDArray[np.intp], NDArray[np.intp], F64]:
        """(point, road) pairs worth projecting, with the nearest sample's s as the start.

        A road is a candidate for a point if one of its samples lies within the road's reach
        (outermost lane border + sample step); the nearest road always is.
        """
        idx = self._index
        pts = np.column_stack([px, py])
        _, nearest = idx.tree.query(pts)
        balls = idx.tree.query_ball_point(pts, r=float(np.max(idx.reach)))
        counts = np.fromiter(map(len, balls), dtype=np.intp, count=len(balls))
        pt = np.concatenate([np.repeat(np.arange(px.size), counts), np.arange(px.size)])
        samp = np.concatenate(
            [
                np.fromiter(chain.from_iterable(balls), dtype=np.intp, count=int(counts.sum())),
                nearest,
            ]
        )
        road = idx.road_of[samp]
        xy = idx.tree.data[samp]
        dist = np.hypot(xy[:, 0] - px[pt], xy[:, 1] - py[pt])
        keep = dist <= idx.reach[road]
        keep[-px.size :] = True  # the nearest road of every point
        pt, road, samp, dist = pt[keep], road[keep], samp[keep], dist[keep]
        order = np.lexsort((dist, road, pt))  # nearest sample first per (point, road)
        pt, road, samp = pt[order], road[order], samp[order]
        first = np.r_[True, (pt[1:] != pt[:-1]) | (road[1:] != road[:-1])]
        return pt[first], road[first], idx.s[samp[first]]

    def _project(self, road: Road, px: F64, py: F64, s0: F64) -> tuple[F64, F64, F64]:
        """Newton projection of points onto the reference line from the guesses ``s0``.

        Returns s (m), t (m) and the along-track residual (m; 0 for a perpendicular foot).
        """
        s = s0.copy()
        for _ in range(60):
            x, y, h, k, _ = self._reference(road, s)
            dx, dy = px - x, py - y
            ch, sh = np.cos(h), np.sin(h)
            f = dx * ch + dy * sh
            t = -dx * sh + dy * ch
            den = np.maximum(1.0 - k * t, 0.2)
            step = np.clip(f / den, -2.0 * SAMPLE_STEP, 2.0 * SAMPLE_STEP)
            s_new = np.clip(s + step, 0.0, road.length)
            done = float(np.max(np.abs(s_new - s), initial=0.0)) < 1e-11
            s = s_new
            if done:
                break
        x, y, h, _, _ = self._reference(road, s)
        dx, dy = px - x, py - y
        ch, sh = np.cos(h), np.sin(h)
        return s, -dx * sh + dy * ch, dx * ch + dy * sh

    @overload
    def world_to_road(self, x: float, y: float) -> tuple[str, int, float, float]: ...
    @overload
    def world_to_road(
        self, x: Values, y: Values
    ) -> tuple[NDArray[np.object_], NDArray[np.int64], F64, F64]: ...

    def world_to_road(self, x: ArrayLike, y: ArrayLike) -> tuple[Any, Any, Any, Any]:
        """Road coordinates of world points x, y (m): (road id, lane id, s (m), t (m)).

        Each point is projected perpendicularly onto the reference lines of the roads near
        it. A road whose lanes contain the point wins (the one with the smallest |t| if
        several overlap, e.g. inside a junction); otherwise the nearest projection is
        returned with lane id 0. Scalars in, scalars out; arrays in, arrays out.
        """
        xb, yb = np.broadcast_arrays(
            np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
        )
        if not (np.all(np.isfinite(xb)) and np.all(np.isfinite(yb))):
            raise InputError("world_to_road", "x/y", "points must be finite numbers (m)")
        shape = xb.shape
        px, py = xb.ravel(), yb.ravel()
        if px.size == 0:
            return (
                np.empty(shape, dtype=object),
                np.zeros(shape, dtype=np.int64),
                np.zeros(shape),
                np.zeros(shape),
            )
        cand_pt, cand_road, cand_s = self._candidates(px, py)
        idx = self._index
        s_all, t_all, k2_all = (
            np.empty(cand_pt.size),
            np.empty(cand_pt.size),
            np.empty(cand_pt.size),
        )
        lane_all = np.zeros(cand_pt.size, dtype=np.int64)
        for ri in np.unique(cand_road):
            m = np.flatnonzero(cand_road == ri)
            road = idx.roads[int(ri)]
            s, t, res = self._project(road, px[cand_pt[m]], py[cand_pt[m]], cand_s[m])
            perp = np.abs(res) <= _PERP_TOL
            s_all[m], t_all[m], k2_all[m] = s, t, np.hypot(t, res)
            lane_all[m] = np.where(perp, self._lane_at(road, s, t), 0)
        k1 = (lane_all == 0).astype(np.int64)
        order = np.lexsort((k2_all, k1, cand_pt))
        first = order[np.r_[True, cand_pt[order][1:] != cand_pt[order][:-1]]]
        ids = np.array([r.id for r in idx.roads], dtype=object)
        rid, lid = ids[cand_road[first]], lane_all[first]
        s_out, t_out = s_all[first], t_all[first]
        if not shape:
            return str(rid[0]), int(lid[0]), float(s_out[0]), float(t_out[0])
        return rid.reshape(shape), lid.reshape(shape), s_out.reshape(shape), t_out.reshape(shape)

    # -- lane graph --------------------------------------------------------------------
    @cached_property
    def lane_graph(self) -> nx.DiGraph:
        """Directed lane graph; nodes ``(road_id, section_index, lane_id)`` (centre lanes
        excluded).

        Node attributes: ``road``, ``section``, ``lane``, ``type`` (lane type), ``s_start``,
        ``s_end`` (m), ``travel`` (+1 along +s, -1 against), ``junction`` ('-1' if none).
        Edge attribute ``kind``:

        * ``successor``: traffic in u continues into v (within a road across lane sections,
          across road links, and across junction connections via their laneLinks);
          ``predecessor``: the mirror edge v -> u.
        * ``left`` / ``right``: v is the adjacent lane on that side of u, seen in u's travel
          direction; ``same_direction`` tells whether v's traffic moves the same way.
        """
        g = nx.DiGraph()
        for road in self.roads.values():
            for i, sec in enumerate(road.sections):
                for lane in sec.left + sec.right:
                    g.add_node(
                        (road.id, i, lane.id),
                        road=road.id,
                        section=i,
                        lane=lane.id,
                        type=lane.type,
                        s_start=sec.s,
                        s_end=sec.s_end,
                        travel=_travel(road, lane),
                        junction=road.junction,
                    )
                order = sec.lane_ids  # by increasing t
                for lo, hi in zip(order[:-1], order[1:], strict=True):
                    a, b = (road.id, i, lo), (road.id, i, hi)
                    ta, tb = g.nodes[a]["travel"], g.nodes[b]["travel"]
                    g.add_edge(a, b, kind="left" if ta > 0 else "right", same_direction=ta == tb)
                    g.add_edge(b, a, kind="right" if tb > 0 else "left", same_direction=ta == tb)
        for road in self.roads.values():
            last = len(road.sections) - 1
            for i, sec in enumerate(road.sections):
                for lane in sec.left + sec.right:
                    for other in lane.successors:
                        self._link(g, road, i, lane.id, "successor", other, last)
                    for other in lane.predecessors:
                        self._link(g, road, i, lane.id, "predecessor", other, last)
        for j in self.junctions.values():
            for c in j.connections:
                inc, con = self.roads.get(c.incoming_road), self.roads.get(c.connecting_road)
                if inc is None or con is None:
                    continue
                isec = 0 if c.incoming_end == "start" else len(inc.sections) - 1
                csec = 0 if c.contact_point == "start" else len(con.sections) - 1
                for la, lb in c.lane_links:
                    self._connect(
                        g, (inc.id, isec, la), c.incoming_end, (con.id, csec, lb), c.contact_point
                    )
        return g

    def _link(
        self, g: nx.DiGraph, road: Road, i: int, lane_id: int, kind: str, other: int, last: int
    ) -> None:
        end: ContactPoint = "end" if kind == "successor" else "start"
        step = 1 if kind == "successor" else -1
        if 0 <= i + step <= last:
            tend: ContactPoint = "start" if step > 0 else "end"
            self._connect(g, (road.id, i, lane_id), end, (road.id, i + step, other), tend)
            return
        link = road.successor if kind == "successor" else road.predecessor
        if link is None or link.element_type != "road" or link.element_id not in self.roads:
            return
        o = self.roads[link.element_id]
        cp: ContactPoint = link.contact_point or "start"
        osec = 0 if cp == "start" else len(o.sections) - 1
        self._connect(g, (road.id, i, lane_id), end, (o.id, osec, other), cp)

    @staticmethod
    def _connect(
        g: nx.DiGraph, a: LaneKey, a_end: ContactPoint, b: LaneKey, b_end: ContactPoint
    ) -> None:
        """Add successor/predecessor edges between lane ``a`` (touching at its ``a_end``) and
        lane ``b`` (at its ``b_end``), oriented by ``a``'s travel direction."""
        if a not in g or b not in g:
            return
        out_of_a = (g.nodes[a]["travel"] > 0) == (a_end == "end")
        src, dst = (a, b) if out_of_a else (b, a)
        g.add_edge(src, dst, kind="successor")
        g.add_edge(dst, src, kind="predecessor")
