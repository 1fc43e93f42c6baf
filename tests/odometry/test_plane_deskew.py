"""The deskewing error of an epoch's planes (:mod:`planodom.odometry.plane_deskew`)."""

from __future__ import annotations

import numpy as np

from planodom.extraction.deskew import deskew_points
from planodom.extraction.planes.fit import deskew_jacobian, tls_fit
from planodom.geometry import Plane, se3_exp, transform_points
from planodom.odometry.plane_deskew import (
    deskew_covariance,
    epoch_span,
    twist_covariance,
    with_deskew_noise,
)
from planodom.scan import Scan

#: the true twist (rad/s, m/s) of the synthetic epoch: a turn with sway, at 5 m/s
TRUE_TWIST = np.array([0.05, -0.08, 0.4, 5.0, 0.1, 0.05])
SPAN = 0.2  # s


def _wall_epoch(rng: np.random.Generator, normal, offset, n=400):
    """A plane's points (n, 3) seen over ``SPAN`` s from a base moving with TRUE_TWIST: the
    points of ``n . p + offset = 0`` (reference frame, a 10 m x 3 m patch) in the base
    frame of their own time, and their times (n,)."""
    normal = np.asarray(normal, float) / np.linalg.norm(normal)
    e1 = np.cross(normal, [0.0, 0.0, 1.0])
    if np.linalg.norm(e1) < 1e-6:
        e1 = np.cross(normal, [1.0, 0.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(normal, e1)
    t = np.sort(rng.uniform(0.0, SPAN, n))
    ab = np.column_stack([rng.uniform(-5, 5, n), rng.uniform(-1.5, 1.5, n)])
    p_ref = -offset * normal + ab[:, :1] * e1 + ab[:, 1:] * e2
    # p_ref = exp(t xi) p_t  ->  p_t = exp(t xi)^-1 p_ref
    p_t = np.array([transform_points(np.linalg.inv(se3_exp(ti * TRUE_TWIST)), p[None])[0]
                    for ti, p in zip(t, p_ref, strict=True)])  # fmt: skip
    return p_t, t


def _fit(points: np.ndarray) -> np.ndarray:
    """(4,) the TLS plane (n, d) of ``points``, its normal towards the origin (d > 0)."""
    c, _, evecs = tls_fit(points)
    n = evecs[:, 2]
    d = -float(n @ c)
    return np.append(n, d) if d > 0 else -np.append(n, d)


def _plane_with_jacobian(p_t, t, twist) -> Plane:
    """The plane fitted to ``p_t`` deskewed with ``twist``, with the extraction's Jacobian
    (times over the span, as :mod:`planodom.extraction.planes.builder`) and a tiny fit
    covariance."""
    pts = deskew_points(p_t, t, twist)
    coef = _fit(pts)
    D = deskew_jacobian(pts, t / np.max(np.abs(t)), coef[:3])
    return Plane(coef[:3], coef[3], covariance=np.eye(4) * 1e-12, deskew_jacobian=D)


def test_twist_covariance_spreads_each_trace_over_three_axes():
    cov = twist_covariance((0.03, 0.5))
    assert np.isclose(np.trace(cov[:3, :3]), 0.03**2)
    assert np.isclose(np.trace(cov[3:, 3:]), 0.5**2)
    assert np.count_nonzero(cov - np.diag(np.diag(cov))) == 0


def test_added_covariance_matches_monte_carlo_refits_of_the_re_deskewed_points():
    """The oracle: twists drawn from N(twist, Sigma), the points deskewed again with each and
    the plane refitted; the sample covariance of (n, d) is the term within sampling error
    (4000 draws: about 2 % on each variance). Fails with the span scaled by 1.1 (checked
    by hand); the sigmas' reading as traces is the test above."""
    rng = np.random.default_rng(7)
    sigma = (np.radians(3.0), 0.3)  # rad/s, m/s: a predicted twist's size on the 2D rig
    cov_twist = twist_covariance(sigma)
    for normal, offset in (([1.0, 0.2, 0.1], 6.0), ([0.1, 0.05, 1.0], 1.8), ([-0.3, 1, 0], 4)):
        p_t, t = _wall_epoch(rng, normal, offset)
        plane = _plane_with_jacobian(p_t, t, TRUE_TWIST)
        term = deskew_covariance(plane, epoch_span(Scan(p_t, t=t)), cov_twist)
        assert term is not None
        draws = rng.multivariate_normal(TRUE_TWIST, cov_twist, size=4000)
        fits = np.array([_fit(deskew_points(p_t, t, xi)) for xi in draws])
        sample = np.cov(fits.T)
        # the term's own directions: variances along its eigenvectors, and the rest
        w, V = np.linalg.eigh(term)
        along = np.einsum("ij,jk,ki->i", V.T, sample, V)
        big = w > 1e-3 * w.max()
        np.testing.assert_allclose(along[big], w[big], rtol=0.08)
        assert np.linalg.norm(sample - term) <= 0.06 * np.linalg.norm(term)


def test_planes_get_the_term_added_to_their_fit_covariance():
    rng = np.random.default_rng(3)
    p_t, t = _wall_epoch(rng, [1.0, 0.0, 0.05], 5.0)
    plane = _plane_with_jacobian(p_t, t, TRUE_TWIST)
    bare = Plane(plane.normal, plane.offset, covariance=np.eye(4) * 1e-6)  # no Jacobian
    unknown = Plane(plane.normal, plane.offset, deskew_jacobian=plane.deskew_jacobian)
    sigma = (0.05, 0.2)
    out = with_deskew_noise([plane, bare, unknown], Scan(p_t, t=t), TRUE_TWIST, sigma)
    span = float(t.max())  # the last point's time, as the extraction takes it
    expected = plane.covariance + deskew_covariance(plane, span, twist_covariance(sigma))
    np.testing.assert_allclose(out[0].covariance, expected, rtol=1e-6)
    assert out[0] is not plane and np.array_equal(out[0].normal, plane.normal)
    assert out[1] is bare and out[2] is unknown  # nothing to add to / nothing known
    assert np.all(np.diag(expected) >= np.diag(plane.covariance))


def test_an_epoch_taken_at_one_instant_or_not_deskewed_gets_nothing():
    rng = np.random.default_rng(5)
    p_t, t = _wall_epoch(rng, [1.0, 0.0, 0.05], 5.0)
    plane = _plane_with_jacobian(p_t, t, TRUE_TWIST)
    sigma = (0.05, 0.2)
    for scan, twist, s in (
        (Scan(p_t, t=np.zeros(len(t))), TRUE_TWIST, sigma),  # one instant: span 0
        (Scan(p_t), TRUE_TWIST, sigma),  # no times
        (Scan(p_t, t=t), None, sigma),  # not deskewed
        (Scan(p_t, t=t), TRUE_TWIST, None),  # no sigma known (deskewed by a given model)
    ):
        assert with_deskew_noise([plane], scan, twist, s)[0] is plane
    # at one instant the Jacobian itself is zero: no time, no smear
    D = deskew_jacobian(p_t, np.zeros(len(t)), plane.normal)
    assert np.all(D == 0.0)
