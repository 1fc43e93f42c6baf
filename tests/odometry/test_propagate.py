"""The covariance propagation's helpers against scipy (independent implementations)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import block_diag
from scipy.spatial.transform import Rotation

from planodom.odometry.propagate import _block_diag, _rpy, _stacked


def test_closed_form_rpy_matches_scipy_zyx():
    rng = np.random.default_rng(3)
    ypr = np.c_[rng.uniform(-np.pi, np.pi, 50), rng.uniform(-1.4, 1.4, 50), rng.uniform(-3, 3, 50)]
    R = Rotation.from_euler("ZYX", ypr).as_matrix()
    np.testing.assert_allclose(_rpy(R), ypr[:, ::-1], rtol=0, atol=1e-12)
    # Near gimbal lock it falls back to the general conversion.
    R_lock = Rotation.from_euler("ZYX", [[0.3, np.pi / 2 - 1e-3, 0.1]]).as_matrix()
    np.testing.assert_allclose(Rotation.from_euler("ZYX", _rpy(R_lock)[:, ::-1]).as_matrix(),
                               R_lock, atol=1e-12)  # fmt: skip


def test_block_diag_matches_scipy():
    rng = np.random.default_rng(4)
    blocks = [rng.normal(size=(n, n)) for n in (3, 4, 1, 2)]
    np.testing.assert_array_equal(_block_diag(blocks), block_diag(*blocks))


def test_stacked_normals_and_blocks_are_scipys_and_numpys():
    """The compiled copy against the former construction (numpy's concatenation, scipy's
    block_diag of the normals' blocks): equal values, for strided and read-only inputs."""
    rng = np.random.default_rng(5)
    for _ in range(20):
        pn, cn = rng.normal(size=(2, 3)), rng.normal(size=(2, 3))
        pc, cc = rng.normal(size=(2, 4, 4)), rng.normal(size=(2, 4, 4))
        pc.flags.writeable = False
        x, S = _stacked(pn, cn[::-1][::-1], pc, np.asfortranarray(cc))
        np.testing.assert_array_equal(x, np.concatenate([pn.ravel(), cn.ravel()]))
        np.testing.assert_array_equal(S, block_diag(*[c[:3, :3] for c in (*pc, *cc)]))


def test_sources_are_the_sorted_distinct_associations():
    from planodom.association import PairAssociations
    from planodom.odometry.relative import SolverDiagnostics, Status

    info = SolverDiagnostics(
        "wocsc", PairAssociations.empty(),
        rotation_pair=np.array([3, 1, 2, 0]), translation_pair=np.array([1, 3, 0, 2]),
    )  # fmt: skip
    # (i1, j1), (i2, j2) of each pair: (3, 2), (1, 0), (1, 0), (3, 2).
    np.testing.assert_array_equal(info.sources(Status.OK), [[1, 0], [3, 2]])
    np.testing.assert_array_equal(info.sources(Status.DEGENERATE), [[1, 0], [3, 2]])
    info = SolverDiagnostics(
        "wocsc", PairAssociations.empty(),
        rotation_pair=np.array([0, 4, 5, 5]), translation_pair=np.array([4, 0, 1, 5]),
    )  # fmt: skip
    np.testing.assert_array_equal(info.sources(Status.OK), [[0, 5], [4, 1], [4, 5]])


def _ground_and_walls(sigmas_deg: list[float]):
    """The ground (z), a wall (x) and a wall (y), unmoved, with isotropic normal covariances
    of ``sigmas_deg`` per tangent axis (1 mm offsets)."""
    from planodom.geometry import Plane
    from planodom.planes import PlaneSet

    planes = []
    for n, s in zip(np.eye(3)[[2, 0, 1]], sigmas_deg, strict=True):
        cov = np.zeros((4, 4))
        cov[:3, :3] = np.radians(s) ** 2 * (np.eye(3) - np.outer(n, n))
        cov[3, 3] = 1e-6
        planes.append(Plane(n, 3.0, covariance=cov))
    return PlaneSet.from_planes(planes)


def test_a_pairs_rotation_covariance_in_closed_form():
    """Ground z (per-axis variance v1 over both epochs) and wall x (v2), no motion. Roll
    (about x) only the ground sees, yaw only the wall, pitch both. The paper's frame with
    the ground first: (v1, v1, v2); the wall first: (v1, v2, v2); fitted to both with
    weights 1 / v: pitch 1 / (1 / v1 + 1 / v2)."""
    from planodom.odometry.propagate import pose_covariance, rotation_covariance

    planes = _ground_and_walls([0.01, 0.3, 0.2])
    v1, v2 = 2 * np.radians(0.01) ** 2, 2 * np.radians(0.3) ** 2
    n, c = planes.normals[:2], planes.covariances[:2]
    tol = dict(rtol=1e-6, atol=1e-16)
    np.testing.assert_allclose(rotation_covariance(n, n, c, c), np.diag([v1, v1, v2]), **tol)
    np.testing.assert_allclose(
        rotation_covariance(n[::-1], n[::-1], c[::-1], c[::-1]), np.diag([v1, v2, v2]), **tol
    )
    weighted = np.diag([v1, 1 / (1 / v1 + 1 / v2), v2])
    w = np.array([1 / v1, 1 / v2])
    np.testing.assert_allclose(rotation_covariance(n, n, c, c, w), weighted, **tol)
    np.testing.assert_allclose(rotation_covariance(n[::-1], n[::-1], c[::-1], c[::-1], w[::-1]),
                               weighted, **tol)  # fmt: skip
    # The joint covariance's rotation block (translation from the two walls) is the same.
    joint = pose_covariance(planes, planes, np.array([0, 1, 0, 1]), np.array([1, 2, 1, 2]),
                            0.0, 0.0, w)  # fmt: skip
    np.testing.assert_allclose(joint[:3, :3], weighted, **tol)
    wall_first, walls = np.array([1, 0, 1, 0]), np.array([1, 2, 1, 2])
    joint = pose_covariance(planes, planes, wall_first, walls, 0.0, 0.0)
    np.testing.assert_allclose(joint[:3, :3], np.diag([v1, v2, v2]), **tol)
