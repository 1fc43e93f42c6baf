"""The moments' residuals and Jacobian compiled (planodom.odometry.moment_kernel) give the
numpy forms' values to the bit: :func:`planodom.oracle._residuals` and
:func:`planodom.odometry.moment_solve.moment_jacobian`, computed independently in numpy, on
random planes and poses (few associations, as an epoch gives, up to many) and along a
solve's iterates."""

import numpy as np
import pytest

from planodom.geometry import se3_exp
from planodom.odometry.moment_kernel import moment_terms
from planodom.odometry.moment_solve import moment_jacobian, moment_solve
from planodom.oracle import SurfaceMoments, _residuals, _roots


def _moments(rng: np.random.Generator, k: int) -> SurfaceMoments:
    n = rng.normal(size=(k, 3))
    n /= np.linalg.norm(n, axis=1)[:, None]
    A = rng.normal(size=(k, 3, 3))
    scatter = A @ np.swapaxes(A, 1, 2) * rng.uniform(0.01, 5.0)
    count = rng.integers(5, 500, size=k).astype(np.float64)
    return SurfaceMoments(np.arange(k), count, 5 * rng.normal(size=(k, 3)), scatter, n,
                          4 * rng.normal(size=k))  # fmt: skip


def _assert_numpys(T: np.ndarray, prev: SurfaceMoments, curr: SurfaceMoments) -> None:
    roots = (_roots(prev.scatter), _roots(curr.scatter))
    r, J = moment_terms(
        T, prev.normal, curr.normal, prev.centroid, curr.centroid, prev.count, curr.count,
        prev.offset, curr.offset, roots[0], roots[1],
    )  # fmt: skip
    want_r, want_J = _residuals(T, prev, curr, roots), moment_jacobian(T, prev, curr, roots)
    assert r.shape == want_r.shape and J.shape == want_J.shape
    assert r.tobytes() == want_r.tobytes()
    assert J.tobytes() == want_J.tobytes()


@pytest.mark.parametrize("seed", range(6))
def test_the_kernel_gives_the_numpy_forms_bits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    for _ in range(60):
        k = int(rng.integers(3, 13))
        T = se3_exp(rng.normal(size=6) * [0.2, 0.2, 0.2, 1.0, 1.0, 0.2])
        _assert_numpys(np.ascontiguousarray(T), _moments(rng, k), _moments(rng, k))


def test_the_kernel_gives_the_numpy_forms_bits_along_a_solve(monkeypatch) -> None:
    """Every pose a solve evaluates (its own iterates, from a start 0.1 rad / 0.5 m off)."""
    import planodom.odometry.moment_solve as ms

    rng = np.random.default_rng(11)
    prev, curr = _moments(rng, 5), _moments(rng, 5)
    seen: list[np.ndarray] = []
    kernel = ms.moment_terms

    def spy(T, *args):  # type: ignore[no-untyped-def]
        seen.append(T.copy())
        return kernel(T, *args)

    monkeypatch.setattr(ms, "moment_terms", spy)
    moment_solve(prev, curr, se3_exp(np.array([0.1, -0.05, 0.1, 0.5, -0.3, 0.1])))
    assert len(seen) >= 3
    for T in seen:
        _assert_numpys(T, prev, curr)
