"""experiments/jacobian_refine.py: the compiled Jacobian and the first-order plane move."""

from __future__ import annotations

import numpy as np
from experiment_scripts import load_script

from planodom.extraction.deskew import deskew_points
from planodom.extraction.planes.fit import deskew_jacobian, tls_fit
from planodom.geometry import Plane, invert_transform, se3_exp

jr = load_script("jacobian_refine")


def _wall(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Points (300, 3) of a tilted wall seen over 0.1 s (times (300,), s, from -0.05)."""
    u, v = rng.uniform(-2, 2, 300), rng.uniform(0, 3, 300)
    n = np.array([0.9, 0.3, 0.1]) / np.linalg.norm([0.9, 0.3, 0.1])
    e1 = np.cross(n, [0.0, 0.0, 1.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    pts = np.array([8.0, 2.0, 0.0]) + u[:, None] * e1 + v[:, None] * e2
    return pts + rng.normal(scale=0.002, size=pts.shape), np.sort(rng.uniform(-0.05, 0.05, 300))


def test_compiled_jacobian_equals_the_library_one() -> None:
    rng = np.random.default_rng(3)
    for _ in range(5):
        pts, t = _wall(rng)
        fit = tls_fit(pts)
        normal = fit[2][:, 2]
        span = float(np.max(np.abs(t)))
        want = deskew_jacobian(pts, t / span, normal, fit)
        got = jr.compiled_jacobian(pts, t / span, normal, fit)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)


def test_moved_plane_matches_the_refit_of_points_deskewed_again() -> None:
    """A wall seen by a sensor moving with the twist ``used`` (its points at their own
    times), fit after deskewing with ``used`` and moved by the fit's Jacobian for ``new``,
    is the fit of the points deskewed with ``new`` to first order: its error is a small
    part of the change itself (ground truth: the refit). Not to second order: the
    Jacobian takes the deskewed points as the rotation's lever arm, off the seen ones by
    ``t v`` (0.2 m at 8 m here), which leaves a few per cent for every size of change;
    a wrong sign or scale of the move would leave 100 % or more."""
    rng = np.random.default_rng(5)
    wall, t = _wall(rng)
    span = float(np.max(np.abs(t)))
    used = np.array([0.01, -0.02, 0.15, 4.0, 0.2, 0.0])
    T_t_ref = invert_transform(se3_exp(t[:, None] * used))  # (N, 4, 4)
    pts = np.einsum("nij,nj->ni", T_t_ref[:, :3, :3], wall) + T_t_ref[:, :3, 3]
    new = used + np.array([0.005, 0.01, np.radians(2.0), 0.3, -0.1, 0.02])
    before = deskew_points(pts, t, used)
    fit = tls_fit(before)
    n = fit[2][:, 2]
    n = n if n @ fit[0] < 0 else -n  # towards the origin (the sensor)
    plane = Plane(
        normal=n, offset=float(-n @ fit[0]),
        deskew_jacobian=deskew_jacobian(before, t / span, n, fit),
    )  # fmt: skip
    moved = jr.moved(plane, (new - used) * span)
    after = tls_fit(deskew_points(pts, t, new))
    n_true = after[2][:, 2] * np.sign(after[2][:, 2] @ n)
    d_true = float(-n_true @ after[0])
    change = np.linalg.norm(np.r_[n_true - plane.normal, d_true - plane.offset])
    error = np.linalg.norm(np.r_[n_true - moved.normal, d_true - moved.offset])
    assert change > 1e-4  # the twist change moves the plane measurably
    assert error < 0.15 * change
