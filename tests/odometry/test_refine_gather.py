"""plane_translation's rows gathered in the compiled call (SPEED2D9) against numpy's
gathering: the same fit, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest

from planodom.odometry.refine import _UNMEASURED, _translation_kernel, gathered_fit
from planodom.planes import PlaneSet


def _planes(rng: np.random.Generator, k: int) -> PlaneSet:
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    a = rng.normal(scale=1e-3, size=(k, 4, 4))
    cov = a @ np.swapaxes(a, 1, 2)
    cov[rng.random(k) < 0.2] = np.nan  # unknown covariances: the kernel's fallback
    return PlaneSet(n, rng.normal(scale=5.0, size=k), rng.uniform(0.1, 1.0, k),
                    rng.normal(size=(k, 3)), rng.uniform(1, 3, k), cov)  # fmt: skip


def _rest(rng: np.random.Generator) -> tuple:
    return (0.866, True, 0.01, 0.05, 0.25, bool(rng.random() < 0.5),
            _UNMEASURED[str(rng.choice(list(_UNMEASURED)))], 0.866, 0.05)  # fmt: skip


@pytest.mark.parametrize("seed", range(8))
def test_gathered_fit_is_numpy_gathers_fit(seed: int) -> None:
    rng = np.random.default_rng(seed)
    prev, curr = _planes(rng, 9), _planes(rng, 7)
    L = int(rng.integers(1, 7))
    ij = np.column_stack([rng.permutation(9)[:L], rng.permutation(7)[:L]]).astype(np.intp)
    i, j = ij[:, 0], ij[:, 1]
    R = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    t0, rest = rng.normal(size=3), _rest(rng)
    got = gathered_fit(prev, curr, i, j, R, t0, rest)
    assert got is not None
    want = _translation_kernel(
        prev.normals[i], prev.offsets[i], prev.covariances[i], curr.normals[j],
        curr.offsets[j], curr.covariances[j], R, t0, *rest,
    )  # fmt: skip
    for a, b in zip(got[:3], want[:3], strict=True):
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    assert got[3] == want[3]


def test_gathered_fit_leaves_other_input_to_numpy() -> None:
    rng = np.random.default_rng(1)
    prev, curr = _planes(rng, 4), _planes(rng, 4)
    R, t0, rest = np.eye(3), np.zeros(3), _rest(rng)
    ok = np.array([0, 1, 2])
    for i, j in ((np.array([0, 4, 1]), ok), (ok, np.array([0, -1, 2]))):  # out of range
        assert gathered_fit(prev, curr, i, j, R, t0, rest) is None
    assert gathered_fit(prev, curr, ok.astype(np.int32), ok, R, t0, rest) is None
    frozen = np.array(prev.normals)
    frozen.flags.writeable = False  # another compiled specialisation: numpy gathers
    other = PlaneSet(frozen, prev.offsets, prev.weights, prev.centroids, prev.radii,
                     prev.covariances)  # fmt: skip
    assert gathered_fit(other, curr, ok, ok, R, t0, rest) is None
    assert gathered_fit(prev, curr, ok, ok, R, t0, rest) is not None
