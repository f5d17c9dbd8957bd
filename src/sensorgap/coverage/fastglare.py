"""Compiled (numba) glare replacement of the lookup: a glared camera's ln(1 - Pd) at the
outline points of target bodies (or at their centres) from its received-signal map, with
each point's veiling glare and the camera's ROC.

It is the built-in camera's ``snr_from_signal`` (models/camera.py: the veil
``k E_dir / theta^2`` as shot and contrast noise beside the object's shot and thermal
noise) with the constants that ``Camera.prepare`` folds
(``PreparedSensor.veil_constants``), the glare factor of ``models.base.glare_factors``
(glare weight times ``min(1, (theta_min / theta)^2)``), and the closed-form ROC kinds of
``fastkernel.roc_constants``. The numpy path (``logmiss._glared_values_numpy``) stays the
reference and the fallback for other sensor types and ROC kinds;
tests/coverage/test_fastglare.py holds the two equal to 1e-12.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.coverage.fastkernel import ROC_SMOOTHSTEP, sensor_frame
from sensorgap.coverage.fastlookup import bilinear_finite_at, place
from sensorgap.jit import njit
from sensorgap.models.numerics import LN10_OVER_10, SNR_CEIL_DB, SNR_FLOOR_DB

F64 = NDArray[np.float64]
F32 = NDArray[np.float32]

#: Largest per-sensor Pd in the log domain (as ``logmiss.ALMOST_ONE``).
_ALMOST_ONE = float(np.nextafter(1.0, 0.0))
_LN2 = math.log(2.0)


@njit(nogil=True, inline="always")
def _logaddexp(x: float, y: float) -> float:  # pragma: no cover - compiled
    """ln(e^x + e^y), as ``numpy.logaddexp``."""
    if x == y:
        return x + _LN2
    d = x - y
    if d > 0.0:
        return x + math.log1p(math.exp(-d))
    if d <= 0.0:
        return y + math.log1p(math.exp(d))
    return d  # NaN


@njit(nogil=True, inline="always")
def roc_log_miss(snr_db: float, code: int, c: F64) -> float:  # pragma: no cover - compiled
    """ln(1 - Pd) of an SNR (dB) under a closed-form ROC (``fastkernel.roc_constants``:
    ``c`` = its two constants and the weather shift, dB), Pd capped below 1 as in
    ``logmiss.log_miss_of``: the steps of ``clip_snr_db``, ``detection_probability`` and
    ``log_miss_of``."""
    s = min(max(snr_db, SNR_FLOOR_DB), SNR_CEIL_DB) - c[2]
    s = min(max(s, SNR_FLOOR_DB), SNR_CEIL_DB)
    if code == ROC_SMOOTHSTEP:
        t = (s - (c[0] - c[1])) / (2.0 * c[1])
        t = min(max(t, 0.0), 1.0)
        pd = t * t * (3.0 - 2.0 * t)
    else:  # paper (0 below the floor) and Swerling 1 (floor -1e300): exp(a / (1 + SNR))
        if s < c[1]:
            return 0.0
        pd = math.exp(c[0] / (1.0 + 10.0 ** (s / 10.0)))
    pd = min(max(pd, 0.0), 1.0)
    return math.log1p(-min(pd, _ALMOST_ONE))


@njit(nogil=True, inline="always")
def camera_signal_db(r: float, az: float, el: float, s: F64) -> float:  # pragma: no cover
    """The built-in camera's received signal, dB (``models/camera.py`` ``signal_db``, with
    the constants of ``PreparedSensor.signal_constants`` ``s``: k, sigma, IFOV and pixel
    count in dB, one-way weather loss dB/m, edge loss dB, hfov and vfov rad) at range r
    (m), sensor-frame azimuth and elevation (rad); the edge loss as
    ``geometry.pattern_loss_db``."""
    lr20 = 20.0 * math.log10(r)
    ne = s[0] + min(s[1] - lr20 - s[2], s[3]) - lr20 - s[4] * r
    if s[5] > 0.0:
        loss = 0.0
        if s[6] > 0.0:
            loss += (2.0 * az / s[6]) ** 2
        if s[7] > 0.0:
            loss += (2.0 * el / s[7]) ** 2
        ne -= s[5] * loss
    return ne


@njit(nogil=True)
def glared_pass(
    signal: F32,
    x0: float,
    y0: float,
    inv_res: float,
    xs: F64,
    ys: F64,
    psi: F64,
    outline: F64,
    z: F64,
    mount: F64,
    sun: F64,
    w: F64,
    veil: F64,
    code: int,
    c: F64,
    view: F64,
    sig_c: F64,
    out: F64,
    state: NDArray[np.int8],
) -> None:  # pragma: no cover - compiled
    """A glared camera at M bodies: for each body m (centre ``xs[m]``, ``ys[m]``, m,
    vehicle frame; heading ``psi[m]``, rad; height ``z[m]``, m) and each of its K
    ``outline`` points ((K, 2), target frame, m; one point (0, 0): the centres):
    ``out[m, k]`` = ln(1 - Pd) with the glare of the sun direction ``sun[m]`` ((M, 3)
    vehicle-frame unit vectors) at glare weight ``w[m]``, where the four cells of the
    ``signal`` map (received signal, dB; NaN out of view; first cell centre ``x0``, ``y0``,
    m; ``inv_res`` cells per m) around the point are in view (``state`` 1); else 0 with
    state 0 (out of view) or 2 (the edge of the view or off the map: the caller evaluates
    it exactly). ``mount``: the camera's position (m); ``veil``: (ln veil-to-object ratio
    at theta_min, ln thermal noise, one-way weather loss dB/m, theta_min deg, sigma dBsm,
    IFOV dB, pixel count dB, ln contrast noise, summation pixels dB). With the
    camera's ``signal_constants`` ``sig_c`` (non-empty) and ``view``
    (``fastkernel.mount_constants``), those points are evaluated exactly here instead: the
    field of view and range at the point and ``camera_signal_db`` there (state 3, or 0 out
    of view)."""
    ln_veil0 = veil[0]
    ln_thermal = veil[1]
    one_way = veil[2]
    t_min = veil[3]
    sigma_db = veil[4]
    ifov_db = veil[5]
    n_pix_db = veil[6]
    ln_cv = veil[7]
    sum_db = veil[8]
    k_out = outline.shape[0]
    for m in range(xs.size):
        cp = math.cos(psi[m])
        sp = math.sin(psi[m])
        for k in range(k_out):
            ox = outline[k, 0]
            oy = outline[k, 1]
            px, py = place(xs[m], ys[m], cp, sp, ox, oy)
            sig, st = bilinear_finite_at(signal, x0, y0, inv_res, px, py)
            if st == 0:  # all four cells out of view
                state[m, k] = 0
                out[m, k] = 0.0
                continue
            dx = px - mount[0]
            dy = py - mount[1]
            dz = z[m] - mount[2]
            if st == 2 and sig_c.size:  # the edge of the view or off the map: exact
                ok, rs, u, v, ws, rho2 = sensor_frame(dx, dy, dz, view)
                st = 3 if ok else 0
                if ok:
                    sig = camera_signal_db(
                        rs, math.atan2(v, u), math.atan2(ws, math.sqrt(rho2)), sig_c
                    )
            state[m, k] = st
            out[m, k] = 0.0
            if st == 0 or st == 2:
                continue
            r = math.sqrt(dx * dx + dy * dy + dz * dz)
            g = 0.0
            if w[m] > 0.0:
                cs = -1.0
                if r > 0.0:
                    cs = (dx * sun[m, 0] + dy * sun[m, 1] + dz * sun[m, 2]) / r
                    if cs != cs:
                        cs = -1.0
                cs = min(max(cs, -1.0), 1.0)
                theta = math.degrees(math.acos(cs))
                g = w[m] * (t_min * t_min / max(theta, t_min) ** 2)
            ln_ne = sig * LN10_OVER_10
            npo_db = min(sigma_db - 20.0 * math.log10(max(r, 1e-300)) - ifov_db, n_pix_db)
            cov_db = max(npo_db, 0.0)
            ln_veil = (
                math.log(max(g, 1e-300))
                + ln_veil0
                + ln_ne
                + (one_way * r + cov_db - npo_db) * LN10_OVER_10
            )
            ln_shot = 0.5 * _logaddexp(ln_ne, ln_veil)
            ln_contrast = ln_cv + ln_veil - 0.5 * min(cov_db, sum_db) * LN10_OVER_10
            ln_noise = _logaddexp(ln_shot, _logaddexp(ln_thermal, ln_contrast))
            out[m, k] = roc_log_miss((ln_ne - ln_noise) / LN10_OVER_10, code, c)
