"""The covariance propagation's helpers against scipy (independent implementations)."""

from __future__ import annotations

import numpy as np
from scipy.linalg import block_diag
from scipy.spatial.transform import Rotation

from planodom.odometry.propagate import _block_diag, _rpy


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
