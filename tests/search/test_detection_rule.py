"""Detection rules: cumulative Pd and M-of-N confirmation, by hand."""

from __future__ import annotations

import numpy as np
import pytest

from sensorgap.errors import InputError
from sensorgap.search.evaluate import DetectionRule, Trace, at_least_m_of_window_batch
from sensorgap.search.metrics import compute_all
from tests.search.metric_oracles import at_least_m_of_window, detection_index


def trace(pd: list[float], rule: DetectionRule) -> Trace:
    n = len(pd)
    z = np.zeros(n)
    return Trace(
        t=np.arange(n) * 0.05,
        x=z,
        y=z,
        pd=np.array(pd),
        ttc=np.full(n, np.inf),
        headway=np.full(n, np.inf),
        distance=z,
        ego_speed=z,
        heading=z,
        collided=False,
        duration_s=n * 0.05,
        rule=rule,
    )


def test_poisson_binomial_by_hand() -> None:
    pd = np.array([0.5, 0.5, 0.9])
    got = at_least_m_of_window(pd, 2, 3)
    # k=0: one cycle, cannot have 2; k=1: 0.5*0.5 = 0.25;
    # k=2: P(>=2 of {0.5,0.5,0.9}) = 0.25*0.1 + 2*0.5*0.5*0.9 + 0.25*0.9 = 0.7
    np.testing.assert_allclose(got, [0.0, 0.25, 0.7], atol=1e-15)
    # the package's batch version (one implementation, row-wise) gives the same
    np.testing.assert_allclose(
        at_least_m_of_window_batch(pd[None, :], 2, 3)[0], [0.0, 0.25, 0.7], atol=1e-15
    )


def test_m_of_n_is_stricter_than_cumulative() -> None:
    pd = [0.9] * 10
    cum = detection_index(trace(pd, DetectionRule()))
    mn = detection_index(trace(pd, DetectionRule(kind="m_of_n", m=3, n=5)))
    assert cum == 1  # 1 - 0.1^2 = 0.99
    # P(>= 3 of 5 at 0.9) = 0.99144 (>= 0.99) first reached with a full window (k = 4)
    assert mn == 4
    assert detection_index(trace([0.5] * 10, DetectionRule(kind="m_of_n", m=3, n=5))) is None
    # the package (compiled batch of one) detects at the same steps: t = 0.05 s and 0.20 s
    assert compute_all(trace(pd, DetectionRule()), ["t_detect_s"])["t_detect_s"] == 0.05
    mn3 = DetectionRule(kind="m_of_n", m=3, n=5)
    assert compute_all(trace(pd, mn3), ["t_detect_s"])["t_detect_s"] == pytest.approx(0.20)
    assert compute_all(trace([0.5] * 10, mn3), ["detected"])["detected"] == 0.0


@pytest.mark.parametrize("text", ["3/5", "cumulative", "1/1"])
def test_parse_ok(text: str) -> None:
    assert DetectionRule.parse(text).label() == text


@pytest.mark.parametrize(
    "text",
    [
        "5/3",
        "0/2",
        "x/y",
        "3-5",
        "60/60",
        "３/5",
        "3/５",
        "²/5",
        " 3/5",
        "3 /5",
        "3/5 ",
        "+3/5",
        "1" * 5000 + "/5",
    ],
)
def test_parse_bad(text: str) -> None:
    with pytest.raises(InputError, match="^detection: "):
        DetectionRule.parse(text)
