"""planView primitives against closed-form values (tolerances stated per assertion)."""

from __future__ import annotations

import math

import numpy as np
import pyclothoids
import pytest
from scipy.integrate import quad
from scipy.special import fresnel

from sensorgap.roads import Arc, Line, ParamPoly3, Poly3, Spiral

S = np.linspace(0.0, 1.0, 41)


def test_line_end_point_and_heading() -> None:
    g = Line(s=10.0, x=3.0, y=-2.0, hdg=0.7, length=120.0)
    x, y, h, k = g.evaluate(S * g.length)
    assert x[-1] == pytest.approx(3.0 + 120.0 * math.cos(0.7), abs=1e-12)
    assert y[-1] == pytest.approx(-2.0 + 120.0 * math.sin(0.7), abs=1e-12)
    assert np.all(h == 0.7) and np.all(k == 0.0)
    assert g.end() == pytest.approx((x[-1], y[-1], 0.7), abs=1e-12)


@pytest.mark.parametrize("curv", [1 / 500, -1 / 150, 0.25])
def test_arc_lies_on_its_circle(curv: float) -> None:
    x0, y0, h0, length = 5.0, 7.0, -0.4, 300.0 if abs(curv) < 0.1 else 20.0
    g = Arc(s=0.0, x=x0, y=y0, hdg=h0, length=length, curvature=curv)
    ds = S * length
    x, y, h, k = g.evaluate(ds)
    r = 1.0 / curv
    cx, cy = x0 - r * math.sin(h0), y0 + r * math.cos(h0)  # centre, left of start if curv > 0
    # radius = 1 / curvature for every sample (1e-9 m)
    np.testing.assert_allclose(np.hypot(x - cx, y - cy), abs(r), atol=1e-9)
    np.testing.assert_allclose(k, curv, rtol=0, atol=0)
    np.testing.assert_allclose(h, h0 + curv * ds, atol=1e-15)
    # closed-form end point (1e-9 m)
    xe = x0 + (math.sin(h0 + curv * length) - math.sin(h0)) / curv
    ye = y0 - (math.cos(h0 + curv * length) - math.cos(h0)) / curv
    assert (x[-1], y[-1]) == pytest.approx((xe, ye), abs=1e-9)


def test_arc_zero_and_tiny_curvature_is_a_line() -> None:
    line = Line(0.0, 1.0, 2.0, 0.3, 1000.0)
    for curv in (0.0, 1e-13):
        arc = Arc(0.0, 1.0, 2.0, 0.3, 1000.0, curvature=curv)
        for a, b in zip(arc.evaluate(S * 1000.0)[:2], line.evaluate(S * 1000.0)[:2], strict=True):
            np.testing.assert_allclose(a, b, atol=1e-6)  # sagitta of 1e-13 over 1 km: 1.3e-8 m


def test_spiral_from_zero_curvature_matches_fresnel() -> None:
    # Clothoid from curvature 0: x = a C(s / a), y = a S(s / a), a = sqrt(pi / c).
    length, k1 = 100.0, 1 / 500
    c = k1 / length
    g = Spiral(0.0, 0.0, 0.0, 0.0, length, curv_start=0.0, curv_end=k1)
    ds = S * length
    x, y, h, k = g.evaluate(ds)
    a = math.sqrt(math.pi / c)
    fs, fc = fresnel(ds / a)
    np.testing.assert_allclose(x, a * fc, atol=1e-9)
    np.testing.assert_allclose(y, a * fs, atol=1e-9)
    np.testing.assert_allclose(h, 0.5 * c * ds**2, atol=1e-15)
    assert k[0] == 0.0 and k[-1] == pytest.approx(k1, rel=1e-14)


@pytest.mark.parametrize(
    ("k0", "k1", "length"), [(0.01, 0.002, 80.0), (-0.02, 0.03, 60.0), (1 / 150, 0.0, 60.0)]
)
def test_spiral_general_against_fresnel_and_curvature_integral(
    k0: float, k1: float, length: float
) -> None:
    x0, y0, h0 = -3.0, 4.0, 1.1
    g = Spiral(0.0, x0, y0, h0, length, curv_start=k0, curv_end=k1)
    ds = S * length
    x, y, h, k = g.evaluate(ds)
    c = (k1 - k0) / length
    # curvature at both ends and linear in between
    assert k[0] == pytest.approx(k0, abs=1e-15) and k[-1] == pytest.approx(k1, abs=1e-15)
    np.testing.assert_allclose(k, k0 + c * ds, atol=1e-15)
    # heading = start heading + integral of the curvature
    np.testing.assert_allclose(h, h0 + k0 * ds + 0.5 * c * ds**2, atol=1e-14)
    # position: completing the square, theta = phi0 + sign(c) pi/2 tau^2,
    # tau = (s + k0/c) sqrt(|c|/pi)  ->  differences of Fresnel integrals
    sig, alpha = math.copysign(1.0, c), math.sqrt(abs(c) / math.pi)
    phi0 = h0 - k0 * k0 / (2.0 * c)
    s_tau, c_tau = fresnel((ds + k0 / c) * alpha)
    s_0, c_0 = fresnel(k0 / c * alpha)
    dc, dsn = c_tau - c_0, s_tau - s_0
    xe = x0 + (math.cos(phi0) * dc - sig * math.sin(phi0) * dsn) / alpha
    ye = y0 + (math.sin(phi0) * dc + sig * math.cos(phi0) * dsn) / alpha
    np.testing.assert_allclose(x, xe, atol=1e-7)  # Fresnel differences lose ~1e-9 relative
    np.testing.assert_allclose(y, ye, atol=1e-7)


def test_spiral_with_equal_curvatures_is_an_arc_and_zero_is_a_line() -> None:
    arc = Arc(0.0, 1.0, 2.0, 0.5, 200.0, curvature=-1 / 300)
    sp = Spiral(0.0, 1.0, 2.0, 0.5, 200.0, curv_start=-1 / 300, curv_end=-1 / 300)
    for a, b in zip(sp.evaluate(S * 200.0), arc.evaluate(S * 200.0), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-10)
    flat = Spiral(0.0, 1.0, 2.0, 0.5, 200.0, curv_start=0.0, curv_end=0.0)
    line = Line(0.0, 1.0, 2.0, 0.5, 200.0)
    for a, b in zip(flat.evaluate(S * 200.0), line.evaluate(S * 200.0), strict=True):
        np.testing.assert_allclose(a, b, atol=1e-12)


def test_spiral_matches_pyclothoids() -> None:
    # an independent clothoid implementation (scenariogeneration's dependency)
    x0, y0, h0, k0, k1, length = 10.0, -5.0, 2.0, 0.05, -0.08, 70.0
    g = Spiral(0.0, x0, y0, h0, length, curv_start=k0, curv_end=k1)
    ref = pyclothoids.Clothoid.StandardParams(x0, y0, h0, k0, (k1 - k0) / length, length)
    ds = S * length
    x, y, _, _ = g.evaluate(ds)
    np.testing.assert_allclose(x, [ref.X(v) for v in ds], atol=1e-9)
    np.testing.assert_allclose(y, [ref.Y(v) for v in ds], atol=1e-9)


def test_poly3_parabola_by_hand() -> None:
    # v = c u^2: arc length S(u) = u sqrt(1 + 4c^2u^2)/2 + asinh(2cu)/(4c)
    c, u_end = 0.01, 60.0
    arc = lambda u: u * math.sqrt(1 + 4 * c * c * u * u) / 2 + math.asinh(2 * c * u) / (4 * c)  # noqa: E731
    x0, y0, h0 = 2.0, 3.0, 0.25
    g = Poly3(0.0, x0, y0, h0, arc(u_end), a=0.0, b=0.0, c=c, d=0.0)
    us = np.array([0.0, 7.5, 30.0, u_end])
    x, y, h, k = g.evaluate(np.array([arc(u) for u in us]))
    lx, ly = us, c * us**2
    np.testing.assert_allclose(x, x0 + lx * math.cos(h0) - ly * math.sin(h0), atol=1e-9)
    np.testing.assert_allclose(y, y0 + lx * math.sin(h0) + ly * math.cos(h0), atol=1e-9)
    np.testing.assert_allclose(h, h0 + np.arctan(2 * c * us), atol=1e-12)
    np.testing.assert_allclose(k, 2 * c / (1 + 4 * c * c * us**2) ** 1.5, rtol=1e-10)


def test_poly3_cubic_against_quadrature() -> None:
    a, b, c, d = 0.5, 0.1, -0.004, 5e-5
    g = Poly3(0.0, 0.0, 0.0, 0.0, 150.0, a=a, b=b, c=c, d=d)
    for u in (0.0, 12.0, 55.0, 100.0):
        s = quad(
            lambda t: math.sqrt(1 + (b + 2 * c * t + 3 * d * t * t) ** 2), 0.0, u, epsabs=1e-13
        )[0]
        x, y, h, k = g.evaluate(np.array([s]))
        dv, ddv = b + 2 * c * u + 3 * d * u * u, 2 * c + 6 * d * u
        assert x[0] == pytest.approx(u, abs=1e-9)
        assert y[0] == pytest.approx(a + b * u + c * u * u + d * u**3, abs=1e-9)
        assert h[0] == pytest.approx(math.atan(dv), abs=1e-12)
        assert k[0] == pytest.approx(ddv / (1 + dv * dv) ** 1.5, rel=1e-9)


def test_param_poly3_arc_length_and_normalized_by_hand() -> None:
    x0, y0, h0, length = 1.0, -1.0, 0.6, 50.0
    cu, du = -0.001, 1e-6
    cv, dv = 0.01, -2e-4
    al = ParamPoly3(
        0.0,
        x0,
        y0,
        h0,
        length,
        a_u=0.0,
        b_u=1.0,
        c_u=cu,
        d_u=du,
        a_v=0.0,
        b_v=0.0,
        c_v=cv,
        d_v=dv,
        p_range="arcLength",
    )
    # the same curve with p in [0, 1]: coefficients scaled by length^n
    nm = ParamPoly3(
        0.0,
        x0,
        y0,
        h0,
        length,
        a_u=0.0,
        b_u=length,
        c_u=cu * length**2,
        d_u=du * length**3,
        a_v=0.0,
        b_v=0.0,
        c_v=cv * length**2,
        d_v=dv * length**3,
        p_range="normalized",
    )
    p = np.array([0.0, 10.0, 25.0, 50.0])
    x, y, h, k = al.evaluate(p)
    u = p + cu * p**2 + du * p**3
    v = cv * p**2 + dv * p**3
    du_, dv_ = 1 + 2 * cu * p + 3 * du * p**2, 2 * cv * p + 3 * dv * p**2
    ddu, ddv = 2 * cu + 6 * du * p, 2 * cv + 6 * dv * p
    np.testing.assert_allclose(x, x0 + u * math.cos(h0) - v * math.sin(h0), atol=1e-12)
    np.testing.assert_allclose(y, y0 + u * math.sin(h0) + v * math.cos(h0), atol=1e-12)
    np.testing.assert_allclose(h, h0 + np.arctan2(dv_, du_), atol=1e-14)
    np.testing.assert_allclose(k, (du_ * ddv - dv_ * ddu) / (du_**2 + dv_**2) ** 1.5, rtol=1e-12)
    for a_, b_ in zip(nm.evaluate(p), (x, y, h, k), strict=True):
        np.testing.assert_allclose(a_, b_, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    "geom",
    [
        Spiral(0.0, 0.0, 0.0, 0.3, 80.0, curv_start=0.01, curv_end=-0.03),
        Poly3(0.0, 0.0, 0.0, 0.0, 90.0, a=0.0, b=0.05, c=0.002, d=-4e-5),
        ParamPoly3(
            0.0,
            0.0,
            0.0,
            0.0,
            40.0,
            a_u=0.0,
            b_u=40.0,
            c_u=-3.0,
            d_u=0.5,
            a_v=0.0,
            b_v=0.0,
            c_v=6.0,
            d_v=-2.0,
            p_range="normalized",
        ),
    ],
)
def test_curvature_rate_matches_finite_differences(geom: Spiral | Poly3 | ParamPoly3) -> None:
    ds = np.linspace(5.0, geom.length - 5.0, 9)
    h = 1e-3
    num = (geom.evaluate(ds + h)[3] - geom.evaluate(ds - h)[3]) / (2 * h)
    if isinstance(geom, ParamPoly3):  # s -> p is linear, not arc length: d/dsigma = d/ds / |P'|
        p = ds / geom.length
        du = np.polyval([3 * geom.d_u, 2 * geom.c_u, geom.b_u], p)
        dv = np.polyval([3 * geom.d_v, 2 * geom.c_v, geom.b_v], p)
        num = num / (np.hypot(du, dv) / geom.length)
    np.testing.assert_allclose(geom.curvature_rate(ds), num, rtol=1e-5, atol=1e-9)


def test_position_derivative_is_the_heading() -> None:
    # d(x, y)/ds = (cos h, sin h) for the arc-length parametrised primitives (1e-7)
    geoms = [
        Arc(0.0, 0.0, 0.0, 0.2, 100.0, curvature=0.02),
        Spiral(0.0, 0.0, 0.0, 0.2, 100.0, curv_start=-0.01, curv_end=0.04),
        Poly3(0.0, 0.0, 0.0, 0.2, 100.0, a=0.0, b=0.0, c=0.003, d=-2e-5),
    ]
    ds, e = np.linspace(1.0, 99.0, 15), 1e-4
    for g in geoms:
        xp, yp, _, _ = g.evaluate(ds + e)
        xm, ym, _, _ = g.evaluate(ds - e)
        _, _, h, _ = g.evaluate(ds)
        np.testing.assert_allclose((xp - xm) / (2 * e), np.cos(h), atol=1e-7)
        np.testing.assert_allclose((yp - ym) / (2 * e), np.sin(h), atol=1e-7)
