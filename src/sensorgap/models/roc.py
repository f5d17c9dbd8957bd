"""SNR -> detection probability (receiver operating characteristics).

Kinds (``RocConfig.kind``):

* ``paper`` (default): Ponn et al. 2019 use ROC curves after Bernsteiner et al. 2013 with
  Pd = 50 % at 10 dB SNR in sunny conditions (Hasch et al. 2012) and curves shifted for
  adverse weather; the curves are not published. We use the Swerling-1 shape anchored at that
  point, ``Pd = 0.5^((1 + SNR50) / (1 + SNR))`` (= ``Pfa^(1/(1+SNR))`` with
  ``Pfa = 0.5^(1 + SNR50)``, 4.9e-4 for 10 dB), which approaches 1 asymptotically, and
  ``Pd = 0`` below ``floor_db`` (no detection is declared from a signal below the floor; the
  paper's blinded cameras have Pd = 0). Why this shape: docs/models.md (Table IV).
* ``smoothstep``: cubic smoothstep in dB, ``Pd = 3t^2 - 2t^3`` with
  ``t = (SNR - shift - snr50 + hw) / (2 hw)`` clipped to [0, 1]: exactly 0 below
  ``snr50 - hw``, exactly 1 above ``snr50 + hw``, monotone, C1.
* ``swerling1``: exact, single pulse, Rayleigh-fluctuating target:
  ``Pd = Pfa^(1/(1+SNR))`` (Richards, Fundamentals of Radar Signal Processing, eq. 6.57).
* ``swerling0``: exact, single pulse, steady target:
  ``Pd = Q1(sqrt(2 SNR), sqrt(-2 ln Pfa))`` (Marcum Q via the non-central chi-square).
* ``albersheim``: Albersheim's approximation (N pulses, non-coherent), inverted for Pd.
  Used only where it is valid (0.1 <= Pd <= 0.9; Pfa 1e-7..1e-3 is checked on load);
  outside that band the exact single-pulse Swerling 0 of the integrated SNR (N * SNR) is
  used instead, documented in docs/models.md.

The weather shift (``EnvironmentConfig.roc_shift_db``) subtracts from the SNR before the
curve: the same detector needs that much more SNR in that weather.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from sensorgap.config.vehicle import RocConfig
from sensorgap.models.numerics import SNR_CEIL_DB, SNR_FLOOR_DB

F64 = NDArray[np.float64]

#: Above this SNR every exact curve is 1 to double precision for any Pfa >= 1e-300, dB.
_SATURATION_DB = 60.0


def _lin(snr_db: F64) -> F64:
    return np.power(10.0, np.clip(snr_db, SNR_FLOOR_DB, _SATURATION_DB) / 10.0)


def pd_paper(snr_db: F64, snr50_db: float, floor_db: float) -> F64:
    """Paper ROC: Swerling-1 shape with Pd(snr50) = 0.5, exactly 0 below ``floor_db``."""
    snr = np.power(10.0, np.clip(snr_db, SNR_FLOOR_DB, SNR_CEIL_DB) / 10.0)
    pd = np.exp(math.log(0.5) * (1.0 + 10.0 ** (snr50_db / 10.0)) / (1.0 + snr))
    return np.where(snr_db < floor_db, 0.0, pd)


def pd_smoothstep(snr_db: F64, snr50_db: float, half_width_db: float) -> F64:
    """Cubic smoothstep in dB; exactly 0 / 1 outside the transition."""
    t = (snr_db - (snr50_db - half_width_db)) / (2.0 * half_width_db)
    t = np.clip(t, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def pd_swerling1(snr_db: F64, pfa: float) -> F64:
    """Exact single-pulse Swerling 1: ``Pfa^(1/(1+SNR))`` evaluated as exp(ln Pfa / (1+SNR)).

    Approaches 1 only slowly (1 - Pd ~ -ln Pfa / SNR), so the SNR is not saturated early.
    """
    snr = np.power(10.0, np.clip(snr_db, SNR_FLOOR_DB, SNR_CEIL_DB) / 10.0)
    return np.exp(math.log(pfa) / (1.0 + snr))


def pd_swerling0(snr_db: F64, pfa: float) -> F64:
    """Exact single-pulse steady target: Marcum Q1(sqrt(2 SNR), sqrt(-2 ln Pfa))."""
    from scipy import stats  # lazily: 0.7 s of import time, only for this exact curve

    snr = _lin(snr_db)
    threshold = -2.0 * math.log(pfa)
    pd = stats.ncx2.sf(threshold, 2.0, 2.0 * snr)
    pd = np.where(snr_db >= _SATURATION_DB, 1.0, pd)
    return np.clip(np.nan_to_num(pd, nan=0.0), pfa, 1.0)


def pd_albersheim_raw(snr_db: F64, pfa: float, n_pulses: int) -> F64:
    """Albersheim's equation inverted for Pd (valid only for 0.1 <= Pd <= 0.9)."""
    a = math.log(0.62 / pfa)
    z = (snr_db + 5.0 * math.log10(n_pulses)) / (6.2 + 4.54 / math.sqrt(n_pulses + 0.44))
    b = (np.power(10.0, np.clip(z, -50.0, 50.0)) - a) / (1.7 + 0.12 * a)
    from scipy import special  # lazily (see pd_swerling0)

    return np.asarray(special.expit(b), dtype=np.float64)


def pd_albersheim(snr_db: F64, pfa: float, n_pulses: int) -> F64:
    """Albersheim inside its validity band, exact Swerling 0 of N * SNR outside it."""
    raw = pd_albersheim_raw(snr_db, pfa, n_pulses)
    valid = (raw >= 0.1) & (raw <= 0.9)
    if bool(np.all(valid)):
        return raw
    exact = pd_swerling0(snr_db + 10.0 * math.log10(n_pulses), pfa)
    return np.where(valid, raw, exact)


def detection_probability(snr_db: F64, roc: RocConfig, shift_db: float = 0.0) -> F64:
    """Pd in [0, 1] for SNR values (dB) under ``roc``, after the weather shift (dB)."""
    s = np.clip(np.asarray(snr_db, dtype=np.float64) - shift_db, SNR_FLOOR_DB, SNR_CEIL_DB)
    if roc.kind == "paper":
        pd = pd_paper(s, roc.snr50_db, roc.floor_db)
    elif roc.kind == "smoothstep":
        pd = pd_smoothstep(s, roc.snr50_db, roc.half_width_db)
    elif roc.kind == "swerling1":
        pd = pd_swerling1(s, roc.pfa)
    elif roc.kind == "swerling0":
        pd = pd_swerling0(s, roc.pfa)
    else:
        pd = pd_albersheim(s, roc.pfa, roc.n_pulses)
    return np.clip(pd, 0.0, 1.0)


def snr_db_for_zero_detection(roc: RocConfig, shift_db: float = 0.0) -> float | None:
    """The SNR (dB) at and below which Pd is exactly 0; ``None`` if the curve never is 0
    (exact curves floor at Pfa)."""
    if roc.kind == "smoothstep":
        return roc.snr50_db - roc.half_width_db + shift_db
    if roc.kind == "paper":
        return roc.floor_db + shift_db
    return None
