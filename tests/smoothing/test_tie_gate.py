"""The tie gate's limit (smoothing.tie_gate) against chi2's closed-form quantiles."""

import numpy as np
import pytest
from scipy.stats import chi2

from planodom.smoothing.tie_gate import tie_gate_limit

Q = 0.999


def _tracked(scale: float, outliers: float, n: int = 200_000) -> np.ndarray:
    """``n`` chi2(3) errors times ``scale`` (a plane covariance off by that factor), a
    fraction ``outliers`` of them replaced by 1e6 (wrong tracked associations)."""
    rng = np.random.default_rng(7)
    x = scale * rng.chisquare(3, n)
    x[: int(outliers * n)] = 1e6
    return x


@pytest.mark.parametrize("mode", ["tail", "bulk"])
def test_a_scaled_chi2_bulk_gives_the_scaled_quantile(mode: str) -> None:
    limit = tie_gate_limit(_tracked(4.0, 0.0), Q, mode)
    assert limit == pytest.approx(4.0 * chi2.ppf(Q, 3), rel=0.05)


def test_outliers_set_the_tail_but_not_the_bulk() -> None:
    tracked = _tracked(4.0, 0.003)  # 0.3 %: above the 0.999 quantile, below the 0.99
    assert tie_gate_limit(tracked, Q, "tail") == 1e6
    bulk = 4.0 * chi2.ppf(0.99 / 0.997, 3)  # the mixture's 0.99 quantile, in the bulk
    expected = bulk * chi2.ppf(Q, 3) / chi2.ppf(0.99, 3)
    assert tie_gate_limit(tracked, Q, "bulk") == pytest.approx(expected, rel=0.05)


@pytest.mark.parametrize("mode", ["tail", "bulk"])
def test_never_below_chi2_nor_without_tracked_factors(mode: str) -> None:
    floor = chi2.ppf(Q, 3)
    assert tie_gate_limit(_tracked(0.1, 0.0), Q, mode) == pytest.approx(floor)
    assert tie_gate_limit(np.zeros(0), Q, mode) == pytest.approx(floor)
