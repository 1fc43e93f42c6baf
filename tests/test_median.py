"""planodom.median against numpy's own median, bit for bit."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from planodom.median import median


def _bits(x: float) -> bytes:
    return np.float64(x).tobytes()


@pytest.mark.parametrize("seed", range(5))
def test_median_equals_numpy_bit_for_bit_on_random_arrays(seed):
    rng = np.random.default_rng(seed)
    for n in [*range(1, 40), 101, 1000, 4097]:
        for draw in (
            rng.normal(size=n),
            rng.exponential(size=n) * 1e-6,
            rng.integers(-3, 4, size=n).astype(float),  # ties
            np.round(rng.normal(size=n), 1) * 0.1,
        ):
            assert _bits(median(draw)) == _bits(float(np.median(draw))), (n, draw)


def test_median_signed_zeros_nan_and_other_inputs():
    for a in ([-0.0, -0.0], [-0.0, 0.0], [0.0, -0.0], [-0.0], [-0.0, 1.0, -0.0]):
        assert _bits(median(np.array(a))) == _bits(float(np.median(a)))
    assert np.isnan(median(np.array([1.0, np.nan, 2.0])))
    assert np.isnan(median(np.array([np.nan, 1.0, 2.0, 3.0, 4.0])))
    assert median([3, 1, 2]) == 2.0  # lists and integers, as np.median
    assert median(np.arange(12.0).reshape(3, 4)) == 5.5  # taken flat
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        assert np.isnan(median(np.zeros(0)))
    v = np.array([5.0, 1.0, 3.0])
    median(v)
    assert v.tolist() == [5.0, 1.0, 3.0]  # the input is not reordered
