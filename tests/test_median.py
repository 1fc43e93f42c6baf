"""planodom.median against numpy's own median, bit for bit."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from planodom.median import block_medians, median, median_at_most


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


def _around(m: float) -> tuple[float, float, float]:
    """``m`` and its neighbouring floats below and above."""
    return m, np.nextafter(m, -np.inf), np.nextafter(m, np.inf)


@pytest.mark.parametrize("seed", range(3))
def test_median_at_most_is_numpys_verdict_at_every_limit_near_the_middle(seed):
    """The counted verdict equals ``np.median(v) <= limit`` for limits at, one ulp around,
    and between the middle values (the ties of an even count: the mean of the two middle
    values and its neighbours decide), on odd and even counts with repeated values."""
    rng = np.random.default_rng(seed)
    for n in (1, 2, 3, 4, 5, 8, 9, 64, 101):
        for v in (rng.normal(size=n), rng.integers(-2, 3, size=n).astype(float)):
            s = np.sort(v)
            mids = {s[(n - 1) // 2], s[n // 2], (0.0 + s[(n - 1) // 2] + s[n // 2]) / 2.0}
            limits = {x for m in mids for x in _around(m)}
            limits |= {s[0], s[-1], -np.inf, np.inf}
            for limit in limits:
                assert median_at_most(v, limit) == bool(np.median(v) <= limit), (v, limit)
    tie = np.array([1.0, 3.0])  # the mean of the two middle values is 2.0
    assert median_at_most(tie, 2.0) and not median_at_most(tie, np.nextafter(2.0, 0.0))
    assert not median_at_most(np.array([0.0, np.nan, 0.0]), 1.0)  # a NaN median
    assert not median_at_most(np.zeros(0), 1.0)
    assert median_at_most(np.array([np.inf, 0.0, 0.0]), 0.0)
    assert not median_at_most(np.array([np.inf, np.inf, 0.0]), 1e300)


@pytest.mark.parametrize("seed", range(3))
def test_block_medians_equal_numpy_per_block_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    sizes = rng.integers(1, 60, size=40)
    sizes[:4] = [1, 2, 3, 4]
    values = np.concatenate([
        rng.normal(size=sizes[0 :: 3].sum()),
        rng.integers(-3, 4, size=sizes[1 :: 3].sum()).astype(float),  # ties
        np.round(rng.normal(size=sizes[2 :: 3].sum()), 1) * 0.1,
    ])  # fmt: skip
    bounds = np.r_[0, np.cumsum(sizes)]
    values = values[: bounds[-1]]
    got = block_medians(values, bounds)
    want = [np.median(values[a:b]) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    assert got.tobytes() == np.array(want).tobytes()


def test_block_medians_signed_zeros_nan_and_empty_blocks():
    blocks = [[-0.0, -0.0], [-0.0, 0.0], [0.0, -0.0], [-0.0], [-0.0, 1.0, -0.0], [1.0, np.nan]]
    values = np.concatenate([np.array(b) for b in blocks])
    bounds = np.r_[0, np.cumsum([len(b) for b in blocks])]
    got = block_medians(values, bounds)
    for k, b in enumerate(blocks[:-1]):
        assert _bits(got[k]) == _bits(float(np.median(b)))
    assert np.isnan(got[-1])
    assert np.isnan(block_medians(np.zeros(3), np.array([0, 0, 3]))[0])  # an empty block
    assert block_medians(np.array([3, 1, 2]), [0, 3])[0] == 2.0  # integers, list bounds
