"""ROC curves against hand-computed values and published reference points."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydantic import ValidationError

from sensorgap.config.vehicle import RocConfig
from sensorgap.models.roc import detection_probability


def pd(snr_db: float, **kw: float | str) -> float:
    return float(detection_probability(np.array([snr_db]), RocConfig(**kw))[0])  # type: ignore[arg-type]


def test_paper_roc_by_hand() -> None:
    # Pd = 0.5 ** ((1 + SNR50) / (1 + SNR)), SNR50 = 10 dB; 0 below the floor (0 dB)
    assert pd(10.0) == pytest.approx(0.5, abs=1e-15)
    assert pd(15.0) == pytest.approx(0.5 ** (11.0 / (1.0 + 10**1.5)), rel=1e-13)  # 0.791
    assert pd(0.0) == pytest.approx(0.5 ** (11.0 / 2.0), rel=1e-13)
    assert pd(-1e-9) == 0.0 and pd(-300.0) == 0.0
    assert pd(300.0) == 1.0
    # the same as exact Swerling 1 at Pfa = 0.5^11 above the floor
    assert pd(7.0) == pytest.approx(pd(7.0, kind="swerling1", pfa=0.5**11), rel=1e-13)


def test_paper_roc_weather_shift() -> None:
    cfg = RocConfig()
    a = detection_probability(np.array([13.0]), cfg, shift_db=3.0)
    assert float(a[0]) == pytest.approx(0.5, abs=1e-15)


def test_smoothstep_roc_by_hand() -> None:
    # t = (s - 4) / 12 for snr50 = 10, hw = 6; Pd = 3t^2 - 2t^3
    assert pd(10.0, kind="smoothstep") == pytest.approx(0.5, abs=1e-15)
    assert pd(7.0, kind="smoothstep") == pytest.approx(3 * 0.25**2 - 2 * 0.25**3, abs=1e-15)
    assert pd(4.0, kind="smoothstep") == 0.0 and pd(-300.0, kind="smoothstep") == 0.0
    assert pd(16.0, kind="smoothstep") == 1.0 and pd(300.0, kind="smoothstep") == 1.0


def snr_for(pd_target: float, **kw: float | str) -> float:
    """SNR (dB) where the curve reaches ``pd_target`` (bisection; curve is monotone)."""
    lo, hi = -20.0, 60.0
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if pd(mid, **kw) < pd_target else (lo, mid)
    return 0.5 * (lo + hi)


def test_swerling1_exact() -> None:
    # Pd = Pfa^(1/(1+SNR)); 21.1 dB for Pd 0.9 at Pfa 1e-6 (physics.md)
    snr = 10**2.11
    assert pd(21.1, kind="swerling1", pfa=1e-6) == pytest.approx(1e-6 ** (1 / (1 + snr)), rel=1e-12)
    assert snr_for(0.9, kind="swerling1", pfa=1e-6) == pytest.approx(21.1, abs=0.05)
    # "50 % at 10 dB" <-> Pfa ~ 4.9e-4 (physics.md)
    assert pd(10.0, kind="swerling1", pfa=4.9e-4) == pytest.approx(0.5, abs=0.01)


def test_swerling0_reference_points() -> None:
    # 13.1 dB for Pd = 0.9 at Pfa = 1e-6 (physics.md, given to 0.1 dB)
    assert snr_for(0.9, kind="swerling0", pfa=1e-6) == pytest.approx(13.1, abs=0.1)
    assert pd(10.0, kind="swerling0", pfa=2.7e-5) == pytest.approx(0.5, abs=0.01)
    # steady target at vanishing SNR: Pd -> Pfa (the false-alarm floor)
    assert pd(-300.0, kind="swerling0", pfa=1e-3) == pytest.approx(1e-3, rel=1e-6)


def test_albersheim_inside_validity_matches_swerling0() -> None:
    # within 0.2 dB of exact Swerling 0 for Pd >= 0.5 (physics.md); 0.2 dB ~ 0.02 in Pd here
    for s in (11.5, 12.0, 12.5, 13.0):
        a = pd(s, kind="albersheim", pfa=1e-6)
        e = pd(s, kind="swerling0", pfa=1e-6)
        assert 0.1 <= a <= 0.9
        assert a == pytest.approx(e, abs=0.03)
    # by hand at 13 dB, N = 1, Pfa 1e-6
    A = math.log(0.62 / 1e-6)
    Z = 13.0 / (6.2 + 4.54 / math.sqrt(1.44))
    B = (10**Z - A) / (1.7 + 0.12 * A)
    assert pd(13.0, kind="albersheim", pfa=1e-6) == pytest.approx(1 / (1 + math.exp(-B)), rel=1e-12)


def test_albersheim_outside_validity_uses_exact() -> None:
    assert pd(30.0, kind="albersheim", pfa=1e-6) == pd(30.0, kind="swerling0", pfa=1e-6)
    assert pd(0.0, kind="albersheim", pfa=1e-6) == pd(0.0, kind="swerling0", pfa=1e-6)


def test_albersheim_rejects_pfa_outside_range() -> None:
    with pytest.raises(ValidationError, match="albersheim"):
        RocConfig(kind="albersheim", pfa=1e-2)


@pytest.mark.parametrize("kind", ["paper", "smoothstep", "swerling0", "swerling1", "albersheim"])
def test_roc_monotone_finite_in_unit_interval(kind: str) -> None:
    s = np.linspace(-400.0, 400.0, 4001)
    p = detection_probability(s, RocConfig(kind=kind, pfa=1e-6))  # type: ignore[arg-type]
    assert np.all(np.isfinite(p))
    assert np.all((p >= 0.0) & (p <= 1.0))
    if kind != "albersheim":  # the documented switch at the validity edge may step
        assert np.all(np.diff(p) >= -1e-15)
    assert p[-1] == pytest.approx(1.0, abs=1e-12)
