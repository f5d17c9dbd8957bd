"""OpenDRIVE planView geometry primitives, evaluated vectorised over the local s.

Each primitive starts at ``(x, y)`` (m, OpenDRIVE inertial frame: x east, y north) with
heading ``hdg`` (rad, counter-clockwise from x) and runs for ``length`` m of arc length.
``evaluate(ds)`` takes the local arc length ``ds = s - s_start`` (m, array) and returns
``x, y`` (m), ``heading`` (rad, not wrapped) and ``curvature`` (1/m, positive = turning
left). ``curvature_rate(ds)`` is d(curvature)/ds (1/m^2), needed for the curvature of
offset (lane) curves.

* ``Line``: straight.
* ``Arc``: constant curvature; evaluated through the chord ``ds * sinc(k ds / 2)``, exact
  and stable down to zero curvature.
* ``Spiral``: clothoid, curvature linear from ``curv_start`` to ``curv_end``. Positions are
  integrals of (cos, sin) of the quadratic heading, done by 12-point Gauss-Legendre
  quadrature on panels over which the heading turns by at most 0.25 rad (error near machine
  precision for any curvatures, including equal start/end and zero curvature, where the
  Fresnel closed form cancels catastrophically).
* ``Poly3``: local ``v(u) = a + b u + c u^2 + d u^3``; ``ds`` is the arc length along the
  cubic, so ``u(ds)`` is found by Newton iteration on the quadrature arc length.
* ``ParamPoly3``: ``u(p), v(p)`` cubics; ``p = ds`` (``pRange="arcLength"``) or
  ``p = ds / length`` (``"normalized"``), the linear mapping of the specification.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
from typing import ClassVar, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

F64 = NDArray[np.float64]
#: x (m), y (m), heading (rad), curvature (1/m).
Pose = tuple[F64, F64, F64, F64]

_GL_X, _GL_W = np.polynomial.legendre.leggauss(12)
#: Largest heading change over one spiral quadrature panel, rad.
_PANEL_TURN = 0.25
_MAX_PANELS = 200_000


def _gauss(fn_values: F64, a: F64, b: F64) -> F64:
    """Sum of Gauss-Legendre weights times ``fn_values`` (shape (..., 12)), scaled to [a, b]."""
    return 0.5 * (b - a) * (fn_values @ _GL_W)


def _nodes(a: F64, b: F64) -> F64:
    """Gauss-Legendre abscissae on [a, b], shape (..., 12)."""
    return (0.5 * (a + b))[..., None] + (0.5 * (b - a))[..., None] * _GL_X


@dataclass(frozen=True)
class Geometry:
    """One ``planView/geometry`` record: start ``s`` (m), start point ``x, y`` (m), start
    heading ``hdg`` (rad) and arc ``length`` (m)."""

    s: float
    x: float
    y: float
    hdg: float
    length: float

    kind: ClassVar[str] = "geometry"

    def evaluate(self, ds: ArrayLike) -> Pose:
        """x, y (m), heading (rad) and curvature (1/m) at local arc length ``ds`` (m)."""
        u = np.asarray(ds, dtype=np.float64)
        lx, ly, lh, k = self._local(u)
        c, s = math.cos(self.hdg), math.sin(self.hdg)
        return self.x + c * lx - s * ly, self.y + s * lx + c * ly, self.hdg + lh, k

    def curvature_rate(self, ds: ArrayLike) -> F64:
        """d(curvature)/ds at local arc length ``ds`` (1/m^2)."""
        return np.zeros_like(np.asarray(ds, dtype=np.float64))

    def end(self) -> tuple[float, float, float]:
        """End point x, y (m) and heading (rad)."""
        x, y, h, _ = self.evaluate(np.array([self.length]))
        return float(x[0]), float(y[0]), float(h[0])

    def _local(self, u: F64) -> Pose:  # pragma: no cover - abstract
        raise NotImplementedError


@dataclass(frozen=True)
class Line(Geometry):
    """Straight line."""

    kind: ClassVar[str] = "line"

    def _local(self, u: F64) -> Pose:
        z = np.zeros_like(u)
        return u.copy(), z, z.copy(), z.copy()


@dataclass(frozen=True)
class Arc(Geometry):
    """Circular arc of constant ``curvature`` (1/m, positive = left)."""

    curvature: float = 0.0

    kind: ClassVar[str] = "arc"

    def _local(self, u: F64) -> Pose:
        phi = self.curvature * u
        chord = u * np.sinc(phi / (2.0 * np.pi))  # 2 sin(k u / 2) / k, exact at k = 0
        return (
            chord * np.cos(0.5 * phi),
            chord * np.sin(0.5 * phi),
            phi,
            np.full_like(u, self.curvature),
        )


@dataclass(frozen=True)
class Spiral(Geometry):
    """Clothoid: curvature linear from ``curv_start`` to ``curv_end`` (1/m) over ``length``."""

    curv_start: float = 0.0
    curv_end: float = 0.0

    kind: ClassVar[str] = "spiral"

    @property
    def rate(self) -> float:
        """Curvature change per metre, 1/m^2."""
        return (self.curv_end - self.curv_start) / self.length

    def _theta(self, u: F64) -> F64:
        return u * (self.curv_start + 0.5 * self.rate * u)

    @cached_property
    def _table(self) -> tuple[F64, F64, F64]:
        """Panel nodes (m) and the cumulative local x, y (m) at them."""
        kmax = max(abs(self.curv_start), abs(self.curv_end))
        n = int(min(max(math.ceil(self.length * kmax / _PANEL_TURN), 1), _MAX_PANELS))
        nodes = np.linspace(0.0, self.length, n + 1)
        t = _nodes(nodes[:-1], nodes[1:])
        th = self._theta(t)
        dx = _gauss(np.cos(th), nodes[:-1], nodes[1:])
        dy = _gauss(np.sin(th), nodes[:-1], nodes[1:])
        return nodes, np.concatenate([[0.0], np.cumsum(dx)]), np.concatenate([[0.0], np.cumsum(dy)])

    def _local(self, u: F64) -> Pose:
        nodes, cx, cy = self._table
        idx = np.clip(np.searchsorted(nodes, u, side="right") - 1, 0, nodes.size - 2)
        a = nodes[idx]
        th = self._theta(_nodes(a, u))
        lx = cx[idx] + _gauss(np.cos(th), a, u)
        ly = cy[idx] + _gauss(np.sin(th), a, u)
        return lx, ly, self._theta(u), self.curv_start + self.rate * u

    def curvature_rate(self, ds: ArrayLike) -> F64:
        """d(curvature)/ds (1/m^2): constant for a clothoid."""
        return np.full_like(np.asarray(ds, dtype=np.float64), self.rate)


def _cubic(c: tuple[float, float, float, float], p: F64) -> tuple[F64, F64, F64, F64]:
    """Value and first three derivatives of ``c0 + c1 p + c2 p^2 + c3 p^3``."""
    a, b, cc, d = c
    return (
        a + p * (b + p * (cc + p * d)),
        b + p * (2.0 * cc + 3.0 * d * p),
        2.0 * cc + 6.0 * d * p,
        np.full_like(p, 6.0 * d),
    )


@dataclass(frozen=True)
class Poly3(Geometry):
    """Cubic ``v(u) = a + b u + c u^2 + d u^3`` in the local (u along hdg, v left) frame;
    the geometry's s runs along the curve's arc length."""

    a: float = 0.0
    b: float = 0.0
    c: float = 0.0
    d: float = 0.0

    kind: ClassVar[str] = "poly3"
    _PANELS: ClassVar[int] = 64

    @property
    def coeffs(self) -> tuple[float, float, float, float]:
        """(a, b, c, d)."""
        return self.a, self.b, self.c, self.d

    def _speed(self, u: F64) -> F64:
        dv = _cubic(self.coeffs, u)[1]
        return np.sqrt(1.0 + dv * dv)

    @cached_property
    def _table(self) -> tuple[F64, F64]:
        """u nodes (m) and arc length at them (m); u never exceeds the arc length."""
        nodes = np.linspace(0.0, self.length, self._PANELS + 1)
        seg = _gauss(self._speed(_nodes(nodes[:-1], nodes[1:])), nodes[:-1], nodes[1:])
        return nodes, np.concatenate([[0.0], np.cumsum(seg)])

    def u_at(self, ds: ArrayLike) -> F64:
        """Local u (m) at arc length ``ds`` (m), by Newton iteration (|error| < 1e-12 m)."""
        s = np.asarray(ds, dtype=np.float64)
        nodes, arc = self._table
        idx = np.clip(np.searchsorted(arc, s, side="right") - 1, 0, nodes.size - 2)
        a = nodes[idx]
        u = a + (s - arc[idx]) * (nodes[idx + 1] - a) / (arc[idx + 1] - arc[idx])
        for _ in range(30):
            err = arc[idx] + _gauss(self._speed(_nodes(a, u)), a, u) - s
            u = u - err / self._speed(u)
            if float(np.max(np.abs(err), initial=0.0)) < 1e-12:
                break
        return u

    def _local(self, ds: F64) -> Pose:
        u = self.u_at(ds)
        v, dv, ddv, _ = _cubic(self.coeffs, u)
        g = 1.0 + dv * dv
        return u, v, np.arctan(dv), ddv / g**1.5

    def curvature_rate(self, ds: ArrayLike) -> F64:
        """d(curvature)/ds (1/m^2)."""
        u = self.u_at(ds)
        _, dv, ddv, d3v = _cubic(self.coeffs, u)
        g = 1.0 + dv * dv
        return (d3v / g**1.5 - 3.0 * dv * ddv * ddv / g**2.5) / np.sqrt(g)


@dataclass(frozen=True)
class ParamPoly3(Geometry):
    """Parametric cubic ``u(p), v(p)`` in the local frame; ``p_range`` is ``"arcLength"``
    (p in [0, length] m) or ``"normalized"`` (p in [0, 1])."""

    a_u: float = 0.0
    b_u: float = 0.0
    c_u: float = 0.0
    d_u: float = 0.0
    a_v: float = 0.0
    b_v: float = 0.0
    c_v: float = 0.0
    d_v: float = 0.0
    p_range: Literal["arcLength", "normalized"] = "normalized"

    kind: ClassVar[str] = "paramPoly3"

    def _p(self, ds: F64) -> F64:
        return ds if self.p_range == "arcLength" else ds / self.length

    def _derivs(self, ds: F64) -> tuple[tuple[F64, F64, F64, F64], tuple[F64, F64, F64, F64]]:
        p = self._p(ds)
        return (
            _cubic((self.a_u, self.b_u, self.c_u, self.d_u), p),
            _cubic((self.a_v, self.b_v, self.c_v, self.d_v), p),
        )

    def _local(self, ds: F64) -> Pose:
        (u, du, ddu, _), (v, dv, ddv, _) = self._derivs(ds)
        q = du * du + dv * dv
        num = du * ddv - dv * ddu
        k = np.divide(num, q**1.5, out=np.zeros_like(q), where=q > 0.0)
        return u, v, np.arctan2(dv, du), k

    def curvature_rate(self, ds: ArrayLike) -> F64:
        """d(curvature)/d(arc length) (1/m^2)."""
        (_, du, ddu, d3u), (_, dv, ddv, d3v) = self._derivs(np.asarray(ds, dtype=np.float64))
        q = du * du + dv * dv
        num = du * ddv - dv * ddu
        dnum = du * d3v - dv * d3u
        dq = 2.0 * (du * ddu + dv * ddv)
        ok = q > 0.0
        qs = np.where(ok, q, 1.0)
        dk_dp = dnum / qs**1.5 - 1.5 * num * dq / qs**2.5
        return np.where(ok, dk_dp / np.sqrt(qs), 0.0)
