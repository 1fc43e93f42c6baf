"""The batch's linear steps (planodom.smoothing.linear_solve) against numpy's least squares."""

import gtsam
import numpy as np
import pytest

from planodom.smoothing.linear_solve import solve, solve_step


def _graph(rows: list[tuple[dict[int, np.ndarray], np.ndarray]]) -> gtsam.GaussianFactorGraph:
    graph = gtsam.GaussianFactorGraph()
    for blocks, b in rows:
        (k1, A1), *rest = blocks.items()
        unit = gtsam.noiseModel.Unit.Create(len(b))
        if rest:
            ((k2, A2),) = rest
            graph.add(k1, A1, k2, A2, b, unit)
        else:
            graph.add(k1, A1, b, unit)
    return graph


def _ordering(keys: list[int]) -> gtsam.Ordering:
    ordering = gtsam.Ordering()
    for key in keys:
        ordering.push_back(key)
    return ordering


def test_a_clique_gtsam_refuses_is_solved_by_cholesky_in_sequence():
    # two scalars tied by one stiff row (a + b, whitened 1e4) and held apart by unit
    # priors: well posed (condition 1e8 of the Hessian), but b's pivot after a is 2e-8 of
    # its assembled diagonal, under gtsam's 2^-24 when both are one clique's frontals
    stiff = 1e4
    rows = [
        ({1: np.array([[stiff]]), 2: np.array([[stiff]])}, np.array([1.0])),
        ({1: np.array([[1.0]])}, np.array([0.5])),
        ({2: np.array([[1.0]])}, np.array([-0.2])),
    ]
    graph, ordering = _graph(rows), _ordering([1, 2])
    with pytest.raises(RuntimeError, match="ndetermina"):
        graph.optimize(ordering)  # the multifrontal check this module works around
    A = np.array([[stiff, stiff], [1.0, 0.0], [0.0, 1.0]])
    expected = np.linalg.lstsq(A, np.array([1.0, 0.5, -0.2]), rcond=None)[0]
    x = solve(graph, ordering)
    # Cholesky's error: about eps times the Hessian's condition number (1e8 here)
    np.testing.assert_allclose([x.at(1)[0], x.at(2)[0]], expected, rtol=1e-6)


def test_a_well_posed_system_is_the_multifrontal_cholesky_solution():
    rng = np.random.default_rng(3)
    rows = [({k: rng.normal(size=(3, 3))}, rng.normal(size=3)) for k in range(4)]
    rows += [
        ({k: rng.normal(size=(3, 3)), k + 1: rng.normal(size=(3, 3))}, rng.normal(size=3))
        for k in range(3)
    ]
    graph, ordering = _graph(rows), _ordering([0, 1, 2, 3])
    x = solve(graph, ordering)
    direct = graph.optimize(ordering)
    for k in range(4):
        np.testing.assert_array_equal(x.at(k), direct.at(k))
    A = np.zeros((21, 12))
    b = np.zeros(21)
    for i, (blocks, rhs) in enumerate(rows):
        for k, block in blocks.items():
            A[3 * i : 3 * i + 3, 3 * k : 3 * k + 3] = block
        b[3 * i : 3 * i + 3] = rhs
    expected = np.linalg.lstsq(A, b, rcond=None)[0]
    np.testing.assert_allclose(np.concatenate([x.at(k) for k in range(4)]), expected, atol=1e-10)


class _RefusingTree:
    """A Bayes tree whose Cholesky shortcuts gtsam refuses (its marginalCovariance raises)."""

    def __init__(self, tree: gtsam.GaussianBayesTree) -> None:
        self.tree = tree

    def marginalCovariance(self, key: int) -> np.ndarray:  # noqa: N802 (gtsam's name)
        raise RuntimeError("Indeterminant linear system detected")

    def marginalFactor(self, key: int, function: object) -> gtsam.GaussianConditional:  # noqa: N802
        return self.tree.marginalFactor(key, function)


def test_a_marginal_whose_cholesky_shortcut_is_refused_comes_from_qr():
    from planodom.smoothing.marginals import _qr_marginal

    rng = np.random.default_rng(5)
    rows = [({k: rng.normal(size=(3, 3))}, rng.normal(size=3)) for k in range(4)]
    rows += [
        ({k: rng.normal(size=(3, 3)), k + 1: 10.0**k * rng.normal(size=(3, 3))}, np.zeros(3))
        for k in range(3)
    ]
    graph = _graph(rows)
    A = np.zeros((21, 12))
    for i, (blocks, _) in enumerate(rows):
        for k, block in blocks.items():
            A[3 * i : 3 * i + 3, 3 * k : 3 * k + 3] = block
    covariance = np.linalg.inv(A.T @ A)  # the exact joint covariance
    tree = graph.eliminateMultifrontal(_ordering([0, 1, 2, 3]), gtsam.EliminateQR)
    for k in range(4):
        expected = covariance[3 * k : 3 * k + 3, 3 * k : 3 * k + 3]
        got = _qr_marginal(_RefusingTree(tree), k)  # type: ignore[arg-type]
        np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12 * np.abs(expected).max())
        np.testing.assert_allclose(_qr_marginal(tree, k), expected, rtol=1e-9)


def _refused_pair() -> tuple[gtsam.GaussianFactorGraph, gtsam.Ordering]:
    """The first test's system: one clique gtsam's multifrontal check refuses."""
    stiff = 1e4
    rows = [
        ({1: np.array([[stiff]]), 2: np.array([[stiff]])}, np.array([1.0])),
        ({1: np.array([[1.0]])}, np.array([0.5])),
        ({2: np.array([[1.0]])}, np.array([-0.2])),
    ]
    return _graph(rows), _ordering([1, 2])


def test_a_step_reports_the_refusal_and_skipping_gives_the_sequential_solution():
    graph, ordering = _refused_pair()
    sequential = graph.eliminateSequential(ordering).optimize()
    for multifrontal in (True, False):
        x, refused = solve_step(graph, ordering, multifrontal)
        assert refused
        assert [x.at(k)[0] for k in (1, 2)] == [sequential.at(k)[0] for k in (1, 2)]
    rng = np.random.default_rng(4)
    rows = [({k: rng.normal(size=(2, 2))}, rng.normal(size=2)) for k in range(3)]
    well = _graph(rows)
    x, refused = solve_step(well, _ordering([0, 1, 2]))
    assert not refused
    direct = well.optimize(_ordering([0, 1, 2]))
    assert all(np.array_equal(x.at(k), direct.at(k)) for k in range(3))


def test_sticky_levenberg_marquardt_skips_only_steps_the_multifrontal_path_refuses(monkeypatch):
    """Two points held by unit priors and tied by a stiff between factor: every step's
    clique is refused, so skipping the multifrontal attempt after the first refusal gives
    the same iterates, bit for bit, and the multifrontal path is tried once."""
    from planodom.smoothing import batch

    tried: list[bool] = []
    original = batch.solve_step

    def recorded(linear, ordering, multifrontal=True):
        tried.append(multifrontal)
        return original(linear, ordering, multifrontal)

    monkeypatch.setattr(batch, "solve_step", recorded)
    graph = gtsam.NonlinearFactorGraph()
    unit, stiff = (
        gtsam.noiseModel.Isotropic.Sigma(2, 1.0),
        gtsam.noiseModel.Isotropic.Sigma(2, 1e-4),
    )
    graph.add(gtsam.PriorFactorPoint2(1, gtsam.Point2(0.5, 0.1), unit))
    graph.add(gtsam.PriorFactorPoint2(2, gtsam.Point2(-0.2, 0.3), unit))
    graph.add(gtsam.BetweenFactorPoint2(1, 2, gtsam.Point2(1.0, 2.0), stiff))
    values = gtsam.Values()
    values.insert(1, gtsam.Point2(3.0, 3.0))
    values.insert(2, gtsam.Point2(-3.0, 1.0))
    plain, plain_errors = batch.levenberg_marquardt(graph, values)
    assert len(tried) >= 2 and all(tried)
    tried.clear()
    sticky, sticky_errors = batch.levenberg_marquardt(graph, values, sticky=True)
    assert tried[0] and not any(tried[1:]) and len(tried) >= 2
    assert sticky_errors == plain_errors
    for k in (1, 2):
        assert np.array_equal(sticky.atPoint2(k), plain.atPoint2(k))
    # the closed form: priors' mean split by the tie (a + (1, 2) = b, equal weights)
    np.testing.assert_allclose(sticky.atPoint2(1), [-0.35, -0.8], atol=1e-6)
