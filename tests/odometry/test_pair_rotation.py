"""An LDA pair's candidate rotation fitted to both normals (planodom.odometry.pair_rotation),
against the truth, scipy's align_vectors, an independent linearised least-squares solve
and the paper's frame it tends to."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from planodom.association import PairAssociations
from planodom.config import PlanodomConfig
from planodom.geometry import Plane, PlaneSupport, rotation_frames, transform_from_rpy_xyz
from planodom.odometry import estimate_relative_pose
from planodom.odometry.pair_rotation import candidate_pairs, weighted_pair_rotations
from planodom.planes import PlaneSet
from tests.planes_factory import noisy, observe, random_motion, square_polygon, world_planes
from tests.pose_checks import pose_error


def _pairs(rng: np.random.Generator, m: int) -> np.ndarray:
    """(m, 2, 3) random pairs of unit normals at least 20 deg from parallel."""
    out = []
    while len(out) < m:
        p = rng.normal(size=(2, 3))
        p /= np.linalg.norm(p, axis=1, keepdims=True)
        if 0.35 < np.linalg.norm(np.cross(p[0], p[1])):
            out.append(p)
    return np.array(out)


def test_exact_normals_give_the_truth_whatever_the_weights() -> None:
    rng = np.random.default_rng(1)
    p = _pairs(rng, 50)
    R_true = Rotation.random(50, random_state=2).as_matrix()
    c = np.einsum("mji,mkj->mki", R_true, p)  # c_k = R^T p_k
    for w in (np.ones((50, 2)), rng.uniform(1e-3, 1e3, (50, 2))):
        np.testing.assert_allclose(weighted_pair_rotations(p, c, w), R_true, rtol=0, atol=1e-12)


def test_noisy_normals_match_scipys_align_vectors() -> None:
    rng = np.random.default_rng(3)
    p = _pairs(rng, 40)
    c = p + rng.normal(scale=0.02, size=p.shape)
    c /= np.linalg.norm(c, axis=2, keepdims=True)
    w = rng.uniform(0.01, 100.0, (40, 2))
    R = weighted_pair_rotations(p, c, w)
    for m in range(40):
        expected = Rotation.align_vectors(p[m], c[m], weights=w[m])[0].as_matrix()
        np.testing.assert_allclose(R[m], expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("seed", range(5))
def test_a_perturbed_normal_splits_its_error_as_least_squares_predicts(seed: int) -> None:
    """One current normal turned by 1e-5 rad: the rotation error is the weighted linear
    least-squares solution of ``sqrt(w_k) (p_k - c_k - theta x c_k) = 0`` (first order)."""
    rng = np.random.default_rng(seed)
    p = _pairs(rng, 1)[0]
    c, k = p.copy(), rng.integers(2)
    c[k] = Rotation.from_rotvec(rng.normal(size=3) * 1e-5).apply(c[k])
    w = rng.uniform(0.1, 10.0, 2)
    A = np.vstack([-np.sqrt(w[k]) * _skew(c[k]) for k in range(2)])  # theta x c = -[c]x theta
    b = np.concatenate([np.sqrt(w[k]) * (p[k] - c[k]) for k in range(2)])
    theta = np.linalg.lstsq(A, b, rcond=None)[0]
    R = weighted_pair_rotations(p[None], c[None], w[None])[0]
    np.testing.assert_allclose(Rotation.from_matrix(R).as_rotvec(), theta, rtol=0, atol=1e-9)


def test_the_split_of_a_tilted_wall_is_its_weight_share() -> None:
    """Ground z and a wall x, the current wall tilted by eps about y (the axis both normals
    see): the fit turns it back by eps * w_wall / (w_ground + w_wall) about y; about x and
    z it does not turn."""
    eps = 1e-6
    p = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])
    c = np.array([[0.0, 0.0, 1.0], [np.cos(eps), 0.0, -np.sin(eps)]])  # x turned about y
    for w in ([1.0, 1.0], [9.0, 1.0], [1.0, 4.0]):
        R = weighted_pair_rotations(p[None], c[None], np.array([w]))[0]
        expected = [0.0, -eps * w[1] / (w[0] + w[1]), 0.0]
        np.testing.assert_allclose(Rotation.from_matrix(R).as_rotvec(), expected, atol=1e-15)


def test_a_dominant_first_weight_gives_the_papers_frame() -> None:
    rng = np.random.default_rng(5)
    p = _pairs(rng, 30)
    c = p + rng.normal(scale=0.03, size=p.shape)
    c /= np.linalg.norm(c, axis=2, keepdims=True)
    paper = rotation_frames(p[:, 0], p[:, 1]) @ np.swapaxes(rotation_frames(c[:, 0], c[:, 1]), 1, 2)
    # the limit is approached as w2 / w1 times the misfit (0.03): 3e-8 at 1e6
    w = np.tile([1e6, 1.0], (30, 1))
    np.testing.assert_allclose(weighted_pair_rotations(p, c, w), paper, rtol=0, atol=3e-7)


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _plane(n, d: float, sigma_deg: float, c) -> Plane:
    """A plane with an isotropic normal covariance of ``sigma_deg`` per tangent axis."""
    n, c = np.asarray(n, dtype=float), np.asarray(c, dtype=float)
    cov = np.zeros((4, 4))
    cov[:3, :3] = np.radians(sigma_deg) ** 2 * (np.eye(3) - np.outer(n, n))
    cov[3, 3] = 1e-6
    return Plane(n, d, covariance=cov, support=PlaneSupport(c, square_polygon(c, n, 3.0), 100))


@pytest.mark.parametrize("mode", ["weighted", "winner"])
@pytest.mark.parametrize("wall_sigma_deg", [0.1, 0.3, 1.0])
def test_the_solver_puts_a_walls_tilt_on_roll_pitch_by_its_weight(
    wall_sigma_deg: float, mode: str
) -> None:
    """Ground and one wall (the wall sorts first), the current wall's normal tilted by 0.5
    deg towards the ground's normal. The paper's candidate fits the wall exactly: the
    whole tilt in the rotation. Weighted, the rotation error is the tilt times the wall's
    weight share (variances of both epochs' planes plus the floor squared)."""
    eps, sg, floor = np.radians(0.5), 0.005, 0.05
    T_true = transform_from_rpy_xyz(0.004, -0.006, 0.03, 0.3, -0.1, 0.0)
    world = [_plane([-1.0, 0, 0], 5.0, 0.0, [5.0, 0, 0]),
             _plane([0, 0, 1.0], 1.5, 0.0, [2, 0, -1.5])]  # fmt: skip
    prev, curr = observe(world, np.eye(4)), observe(world, T_true)
    sigmas = [wall_sigma_deg, sg]
    prev = [
        _plane(q.normal, q.offset, s, q.support.centroid) for q, s in zip(prev, sigmas, strict=True)
    ]
    wall = curr[0]
    axis = np.cross(wall.normal, curr[1].normal)
    tilted = Rotation.from_rotvec(eps * axis / np.linalg.norm(axis)).apply(wall.normal)
    curr = [_plane(tilted, wall.offset, wall_sigma_deg, wall.support.centroid),
            _plane(curr[1].normal, curr[1].offset, sg, curr[1].support.centroid)]  # fmt: skip
    first = estimate_relative_pose(prev, curr)
    weighted = estimate_relative_pose(
        prev, curr, PlanodomConfig().updated({"odometry.pair_rotation": mode})
    )
    # per tangent axis, both epochs: 2 sigma^2, plus the floor
    var_w = 2 * np.radians(wall_sigma_deg) ** 2 + np.radians(floor) ** 2
    var_g = 2 * np.radians(sg) ** 2 + np.radians(floor) ** 2
    share = (1 / var_w) / (1 / var_w + 1 / var_g)
    assert pose_error(first.T_prev_curr, T_true)[0] == pytest.approx(eps, rel=1e-3)
    assert pose_error(weighted.T_prev_curr, T_true)[0] == pytest.approx(eps * share, rel=1e-3)


def test_the_papers_candidates_are_kept_when_off() -> None:
    """Default (``first``): the solver's candidates are the paper's ``U_k U_{k+d}^T``,
    computed here from the frames, and :func:`candidate_pairs` returns LDA's own."""
    rng = np.random.default_rng(7)
    world = world_planes(rng, 5)
    prev = noisy(observe(world, np.eye(4)), rng, 0.01, 0.01)
    curr = noisy(observe(world, random_motion(rng)), rng, 0.01, 0.01)
    cfg = PlanodomConfig()
    assert cfg.odometry.pair_rotation == "first"
    lda = estimate_relative_pose(prev, curr, cfg).diagnostics.lda  # type: ignore[union-attr]
    P, C = PlaneSet.from_planes(prev), PlaneSet.from_planes(curr)
    n_p, n_c = P.normals[lda.prev_pairs], C.normals[lda.curr_pairs]
    paper = rotation_frames(n_p[:, 0], n_p[:, 1]) @ np.swapaxes(
        rotation_frames(n_c[:, 0], n_c[:, 1]), 1, 2
    )
    assert len(lda) > 0
    np.testing.assert_allclose(lda.rotations, paper, rtol=0, atol=1e-12)
    same = PairAssociations(lda.prev_pairs, lda.curr_pairs, lda.rotations, lda.weights)
    assert candidate_pairs(P, C, same, cfg.odometry) is same


def test_winner_keeps_the_papers_winner_and_fits_its_pair_as_scipy_does() -> None:
    """``winner``: the same consensus winner as the paper's; its rotation is scipy's
    ``align_vectors`` of the winner's two normal associations weighted by the inverse of
    their normal variances plus the floor (an independent solve)."""
    rng = np.random.default_rng(11)
    world = world_planes(rng, 5)
    T_true = random_motion(rng)
    prev, curr = (
        [_plane(q.normal, q.offset, s, q.support.centroid) for q, s in zip(ps, sig, strict=True)]
        for ps, sig in (
            (noisy(observe(world, np.eye(4)), rng, 0.003, 0.01), rng.uniform(0.05, 0.5, 6)),
            (noisy(observe(world, T_true), rng, 0.003, 0.01), rng.uniform(0.05, 0.5, 6)),
        )
    )
    paper = estimate_relative_pose(prev, curr)
    cfg = PlanodomConfig().updated(
        {"odometry.pair_rotation": "winner", "odometry.refinement": "none"}
    )
    winner = estimate_relative_pose(prev, curr, cfg)
    pair = paper.diagnostics.rotation_pair  # type: ignore[union-attr]
    np.testing.assert_array_equal(winner.diagnostics.rotation_pair, pair)  # type: ignore[union-attr]
    n_p = np.array([prev[i].normal for i in pair[:2]])
    n_c = np.array([curr[j].normal for j in pair[2:]])
    var = [
        (np.trace(prev[i].covariance[:3, :3]) + np.trace(curr[j].covariance[:3, :3])) / 2
        for i, j in zip(pair[:2], pair[2:], strict=True)
    ]
    w = 1.0 / (np.array(var) + np.radians(cfg.odometry.refine_normal_floor_deg) ** 2)
    expected = Rotation.align_vectors(n_p, n_c, weights=w)[0].as_matrix()
    np.testing.assert_allclose(winner.T_prev_curr[:3, :3], expected, rtol=0, atol=1e-12)
