"""Fusion, eq. 11: by hand, stability at 0 and 1, and properties (hypothesis)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from sensorgap.models.fusion import fuse

probs = st.lists(st.floats(min_value=0.0, max_value=1.0), min_size=1, max_size=12)


def test_fusion_by_hand() -> None:
    p = fuse([np.array([0.5]), np.array([0.5]), np.array([0.2])])
    assert float(p[0]) == pytest.approx(1 - 0.5 * 0.5 * 0.8, abs=1e-15)


def test_fusion_exact_one_and_zero() -> None:
    p = fuse([np.array([1.0, 0.0, 0.0]), np.array([0.3, 0.0, 1.0])])
    assert p.tolist() == [1.0, 0.0, 1.0]
    assert not np.signbit(p).any()  # never -0.0


def test_fusion_keeps_tiny_probabilities() -> None:
    # 1 - (1 - 1e-20)^2 is 0 in naive float64; the log form keeps 2e-20 (rel 1e-12)
    p = fuse([np.array([1e-20]), np.array([1e-20])])
    assert float(p[0]) == pytest.approx(2e-20, rel=1e-12)


@given(probs)
def test_fused_at_least_max_and_at_most_one(ps: list[float]) -> None:
    f = float(fuse([np.array([p]) for p in ps])[0])
    assert max(ps) - 1e-15 <= f <= 1.0


@given(probs, st.randoms(use_true_random=False))
def test_fusion_order_invariant(ps: list[float], rnd: object) -> None:
    shuffled = list(ps)
    rnd.shuffle(shuffled)  # type: ignore[attr-defined]
    a = float(fuse([np.array([p]) for p in ps])[0])
    b = float(fuse([np.array([p]) for p in shuffled])[0])
    assert a == pytest.approx(b, abs=1e-15)
