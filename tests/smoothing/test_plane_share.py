"""``smoothing.sandwich_plane_share`` "own" (planodom.smoothing.plane_share): each plane's
own share of its epoch's deskewing error against gtsam's tangent coordinates, and the
sandwich without the own blocks against the Monte-Carlo covariance of the estimator whose
plane factors weigh that share."""

from __future__ import annotations

import gtsam
import numpy as np
import pytest
from smoothing.test_sandwich import _graph as _sandwich_graph
from smoothing.test_sandwich import _monte_carlo_covariances, _perturbed, _world

from planodom.config import PlanodomConfig, SmoothingConfig
from planodom.errors import ConfigError
from planodom.geometry import Plane
from planodom.smoothing.batch import smooth_batch
from planodom.smoothing.plane_share import own_share
from planodom.smoothing.sandwich import sandwich_covariances
from planodom.smoothing.synthetic import make_sequence, with_deskew_jacobians
from planodom_factors.planes import predict_plane


def test_own_share_is_the_tangent_covariance_of_the_moved_plane() -> None:
    """Planes moved by ``J dxi`` (dxi drawn from q, 20 000 draws): the covariance of
    gtsam's ``localCoordinates`` of the moved plane is ``own_share`` (within 5 %)."""
    rng = np.random.default_rng(5)
    n = np.array([0.3, -0.8, 0.2])
    z = np.append(n / np.linalg.norm(n), 2.5)
    J = rng.normal(scale=0.5, size=(4, 6))
    q = np.diag([1e-6, 2e-6, 4e-7, 3e-6, 1e-6, 5e-7])
    plane = Plane(z[:3], float(z[3]), deskew_jacobian=J)
    base = gtsam.OrientedPlane3(z)
    draws = rng.multivariate_normal(np.zeros(6), q, size=20000)
    tangent = np.array([base.localCoordinates(gtsam.OrientedPlane3(_perturbed(z, J @ d)))
                        for d in draws])  # fmt: skip
    mc = tangent.T @ tangent / len(tangent)
    want = own_share(plane, q)
    np.testing.assert_allclose(mc, want, rtol=0.05, atol=0.05 * np.abs(want).max())
    assert np.array_equal(own_share(Plane(z[:3], float(z[3])), q), np.zeros((3, 3)))


def _graph(poses, walls, measured, between, sig_plane, sig_between, Q, own):  # noqa: ANN001, ANN202, PLR0913
    """The sandwich test's graph; with ``own`` each plane factor's noise holds its share of
    ``Q[k]`` (the option's noise model)."""
    share = (lambda k, plane: own_share(plane, Q[k])) if own else None
    return _sandwich_graph(poses, walls, measured, between, sig_plane, sig_between, share)


def test_sandwich_without_the_own_blocks_is_the_monte_carlo_covariance() -> None:
    """Planes perturbed by their fit noise plus one change of motion per epoch through
    their deskewing Jacobians, solved with each plane factor weighing its own share: the
    poses' covariance over 400 seeded samples matches the sandwich with ``own`` (diagonal
    within 20 %); the sandwich that keeps the own blocks as well (counting them twice) is
    above it by more than that on most axes."""
    poses, walls = _world()
    truth = {(k, j): predict_plane(T.matrix(), w) for k, T in enumerate(poses)
             for j, w in enumerate(walls)}  # fmt: skip
    rel = [poses[k].between(poses[k + 1]) for k in range(len(poses) - 1)]
    sig_plane, sig_between = np.array([2e-4, 2e-4, 1e-3]), 0.05
    Q = np.stack([np.diag([1e-6] * 3 + [4e-6] * 3) * (1 + k) for k in range(len(poses))])
    args = (sig_plane, sig_between, Q, True)
    graph, planes, values = _graph(poses, walls, truth, rel, *args)
    out, note = sandwich_covariances(graph, values, len(poses), planes, Q, False, 1e-6, own=True)
    twice, _ = sandwich_covariances(graph, values, len(poses), planes, Q, False, 1e-6)
    assert note is None
    mc = _monte_carlo_covariances(
        lambda measured, between: _graph(poses, walls, measured, between, *args)[0],
        poses, truth, rel, sig_plane, sig_between, Q, values,
    )  # fmt: skip
    ratios = []
    for k in range(1, len(poses)):
        var_mc = np.diag(mc[k])
        np.testing.assert_allclose(var_mc, np.diag(out.covariances[k]), rtol=0.2)
        ratios.append(np.diag(twice.covariances[k]) / var_mc)
    assert np.median(ratios) > 1.2


def test_batch_with_and_without_the_share() -> None:
    """smooth_batch: "own" moves the poses where the epochs' motion changes and leaves the
    covariances finite and positive; on scans taken at one instant (no deskewing error)
    it is the default, bit for bit."""
    seq = make_sequence(15, seed=4, sigma_rotation=2e-4, sigma_translation=5e-3,
                        sigma_normal=1e-3, sigma_offset=5e-3)  # fmt: skip
    base = SmoothingConfig(loop_closure=False, covariance_model="sandwich")
    own = base.model_copy(update={"sandwich_plane_share": "own"})
    for spread in (True, False):
        planes, relatives = with_deskew_jacobians(seq, spread=spread)
        a, b = smooth_batch(planes, relatives, base), smooth_batch(planes, relatives, own)
        assert a.covariances is not None and b.covariances is not None
        if spread:
            assert not np.array_equal(a.poses, b.poses)
            assert np.all(np.linalg.eigvalsh(b.covariances[1:]) > 0)
        else:
            assert np.array_equal(a.poses, b.poses)
            assert np.array_equal(a.covariances, b.covariances)


def test_option_values() -> None:
    assert SmoothingConfig().sandwich_plane_share == "off"
    with pytest.raises(ConfigError, match="smoothing.sandwich_plane_share"):
        PlanodomConfig().updated({"smoothing.sandwich_plane_share": "planes"})
    for field, value in (("covariance_model", "fitted"), ("deskew_noise", "twist_change"),
                         ("covariance_scale", "posterior")):  # fmt: skip
        with pytest.raises(ConfigError, match="sandwich_plane_share"):
            PlanodomConfig().updated(
                {"smoothing.sandwich_plane_share": "own", f"smoothing.{field}": value}
            )
