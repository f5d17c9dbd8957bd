"""Typed records of an OpenDRIVE road network (what ``read_opendrive`` builds).

Units: s, t, widths and offsets in m; polynomial coefficients in m, 1, 1/m, 1/m^2.
Lane ids follow OpenDRIVE: 0 is the centre lane (no width), positive ids lie left of the
reference line (positive t), negative ids right of it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sensorgap.roads.geometry import Geometry

F64 = NDArray[np.float64]
ContactPoint = Literal["start", "end"]


@dataclass(frozen=True)
class CubicPiece:
    """One cubic record ``f(ds) = a + b ds + c ds^2 + d ds^3`` valid from ``s`` (m) on,
    with ``ds`` measured from ``s`` (laneOffset: road s; lane width: sOffset in the section)."""

    s: float
    a: float
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0


def eval_pieces(pieces: tuple[CubicPiece, ...], s: ArrayLike) -> tuple[F64, F64, F64]:
    """Piecewise cubic value, first and second derivative at ``s`` (same frame as the
    pieces' ``s``). Before the first piece the first piece is extrapolated (at most 1 mm: the
    reader starts laneOffsets with a zero record at s = 0 and a lane's first width record
    within 1 mm of its section start); no pieces -> 0."""
    x = np.asarray(s, dtype=np.float64)
    if not pieces:
        z = np.zeros_like(x)
        return z, z.copy(), z.copy()
    starts = np.array([p.s for p in pieces])
    co = np.array([[p.a, p.b, p.c, p.d] for p in pieces])
    idx = np.clip(np.searchsorted(starts, x, side="right") - 1, 0, len(pieces) - 1)
    u = x - starts[idx]
    a, b, c, d = co[idx, 0], co[idx, 1], co[idx, 2], co[idx, 3]
    return (a + u * (b + u * (c + u * d)), b + u * (2.0 * c + 3.0 * d * u), 2.0 * c + 6.0 * d * u)


@dataclass(frozen=True)
class Lane:
    """One lane of a lane section.

    Attributes:
        id: OpenDRIVE lane id (> 0 left, < 0 right, 0 centre).
        type: OpenDRIVE lane type (``driving``, ``sidewalk``, ``shoulder``, ...).
        widths: width records (``s`` = sOffset from the section start, m).
        predecessors / successors: linked lane ids (OpenDRIVE ``link``; in the road's s sense).
        direction: 1.7 ``@direction`` (``standard``, ``reversed`` or ``both``).
    """

    id: int
    type: str
    widths: tuple[CubicPiece, ...] = ()
    predecessors: tuple[int, ...] = ()
    successors: tuple[int, ...] = ()
    direction: str = "standard"

    def width(self, ds: ArrayLike) -> F64:
        """Width (m) at ``ds`` m from the section start."""
        return eval_pieces(self.widths, ds)[0]


@dataclass(frozen=True)
class LaneSection:
    """A lane section from ``s`` to ``s_end`` (m, road s).

    ``left`` holds lanes 1, 2, ... (inner to outer), ``right`` lanes -1, -2, ...
    """

    s: float
    s_end: float
    left: tuple[Lane, ...]
    center: Lane
    right: tuple[Lane, ...]

    @property
    def lane_ids(self) -> tuple[int, ...]:
        """All non-centre lane ids ordered by t (rightmost first)."""
        return tuple([ln.id for ln in reversed(self.right)] + [ln.id for ln in self.left])

    def lane(self, lane_id: int) -> Lane | None:
        """The lane with ``lane_id`` (0 = centre) or ``None``."""
        if lane_id == 0:
            return self.center
        side = self.left if lane_id > 0 else self.right
        k = abs(lane_id) - 1
        return side[k] if k < len(side) else None


@dataclass(frozen=True)
class RoadLink:
    """A road's predecessor or successor: a road (with the contact point on it) or a junction."""

    element_type: Literal["road", "junction"]
    element_id: str
    contact_point: ContactPoint | None = None


@dataclass(frozen=True)
class Road:
    """One OpenDRIVE road.

    Attributes:
        id: road id (a string, as in the file).
        length: road length, m.
        junction: id of the junction this road belongs to, ``"-1"`` if none.
        geometries: planView records ordered by s.
        lane_offsets: laneOffset records (road s), shift of the centre lane in t, m; the
            reader adds a zero record at s = 0 when the first starts later (no offset
            before the first record, as in OpenDRIVE).
        sections: lane sections ordered by s.
        predecessor / successor: road links (or ``None``).
        rule: traffic rule, ``RHT`` (right-hand traffic, default) or ``LHT``.
        name: road name ('' if none).
    """

    id: str
    length: float
    junction: str
    geometries: tuple[Geometry, ...]
    lane_offsets: tuple[CubicPiece, ...]
    sections: tuple[LaneSection, ...]
    predecessor: RoadLink | None = None
    successor: RoadLink | None = None
    rule: Literal["RHT", "LHT"] = "RHT"
    name: str = ""

    def section_index(self, s: ArrayLike) -> NDArray[np.intp]:
        """Index of the lane section containing road ``s`` (m); a section owns [s_i, s_i+1)."""
        starts = np.array([sec.s for sec in self.sections])
        idx = np.searchsorted(starts, np.asarray(s, dtype=np.float64), side="right") - 1
        return np.clip(idx, 0, len(self.sections) - 1)

    def extents(self, s: ArrayLike) -> tuple[F64, F64]:
        """t (m) of the outer border of the leftmost and of the rightmost lane at road ``s``
        (m, array)."""
        x = np.asarray(s, dtype=np.float64)
        off = eval_pieces(self.lane_offsets, x)[0]
        left, right = off.copy(), off.copy()
        secs = self.section_index(x)
        for i in np.unique(secs):
            m = secs == i
            sec = self.sections[int(i)]
            ds = x[m] - sec.s
            left[m] += sum((ln.width(ds) for ln in sec.left), np.zeros(ds.shape))
            right[m] -= sum((ln.width(ds) for ln in sec.right), np.zeros(ds.shape))
        return left, right


@dataclass(frozen=True)
class Connection:
    """A junction connection: traffic from ``incoming_road`` continues on
    ``connecting_road`` (``linkedRoad`` for direct junctions) entered at ``contact_point``.
    ``lane_links`` are (incoming lane id, connecting lane id) pairs; ``incoming_end`` is the
    end of the incoming road that touches the junction (derived from its road links)."""

    id: str
    incoming_road: str
    connecting_road: str
    contact_point: ContactPoint
    lane_links: tuple[tuple[int, int], ...] = ()
    incoming_end: ContactPoint = "end"


@dataclass(frozen=True)
class Junction:
    """An OpenDRIVE junction (``type`` is ``default``, ``direct`` or ``virtual``)."""

    id: str
    name: str = ""
    type: str = "default"
    connections: tuple[Connection, ...] = field(default=())
