"""The shared compiled helpers of the extraction against numpy."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.extraction.kernels import median_nonnegative


def _samples(kind: str, n: int, rng: np.random.Generator) -> np.ndarray:
    if kind == "noise":
        return np.abs(rng.normal(size=n)) * 1e-3
    if kind == "ties":
        return rng.integers(0, 5, n).astype(np.float64)
    if kind == "zeros":
        return np.zeros(n)
    if kind == "heavy":
        return np.abs(rng.standard_cauchy(n))
    return np.concatenate([np.full(n // 2, 0.5), rng.uniform(0, 1, n - n // 2)])


@pytest.mark.parametrize("kind", ["noise", "ties", "zeros", "heavy", "half-repeated"])
def test_median_nonnegative_is_numpys_median_exactly(kind):
    rng = np.random.default_rng(len(kind))
    for n in [1, 2, 3, 4, 31, 32, 33, 34, 100, 101, 4096, 8603, 8604]:
        a = _samples(kind, n, rng)
        padded = np.concatenate([a, rng.normal(size=5)])  # values beyond n are ignored
        assert median_nonnegative(padded, n) == np.median(a), (kind, n)


def test_median_of_tiny_values_and_subnormals():
    a = np.array([5e-324, 0.0, 1e-310, 3e-308, 2.5e-320, 1e300])
    for n in range(1, len(a) + 1):
        assert median_nonnegative(a, n) == np.median(a[:n])
