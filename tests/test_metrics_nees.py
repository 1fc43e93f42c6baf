"""pose_nees against a Monte Carlo draw from the covariance (chi2) and closed forms."""

from __future__ import annotations

import gtsam
import numpy as np
from scipy.stats import chi2

from planodom.metrics import pose_nees


def test_nees_of_samples_from_the_covariance_is_chi2():
    rng = np.random.default_rng(3)
    n = 2000
    A = rng.normal(size=(6, 6)) * 0.01
    P = A @ A.T + 1e-6 * np.eye(6)
    T = gtsam.Pose3(gtsam.Rot3.Ypr(0.3, -0.1, 0.05), np.array([4.0, -2.0, 0.5]))
    xi = rng.multivariate_normal(np.zeros(6), P, n)
    truth = np.stack([T.retract(x).matrix() for x in xi])
    poses = np.repeat(T.matrix()[None], n, axis=0)
    covs = np.repeat(P[None], n, axis=0)
    for dof in (6, 5):
        v = pose_nees(poses, covs, truth, range(dof))
        lo, hi = chi2.ppf([0.005, 0.995], dof * n) / n
        assert lo < v.mean() < hi, (dof, v.mean())


def test_nees_closed_form_and_singular_blocks():
    T = np.eye(4)
    G = np.eye(4)
    G[0, 3] = 0.2  # 0.2 m along x: xi = (0, 0, 0, 0.2, 0, 0)
    P = np.diag([1e-4] * 3 + [0.01] * 3)
    np.testing.assert_allclose(pose_nees(T[None], P[None], G[None]), [4.0], rtol=1e-9)
    singular = np.zeros((1, 6, 6))
    assert np.isnan(pose_nees(T[None], singular, G[None])[0])
