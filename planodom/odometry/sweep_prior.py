"""The motion inside an epoch as a MAP estimate (``sweep_refine.prior: twist``).

:func:`planodom.odometry.sweep_motion.epoch_motion` fits the correction's coefficients to
the reference epoch's planes as if those were exact; with noise they are not, and the
points of one plane share its error, so thousands of points carry only a few planes'
worth of information, and the coefficients follow the planes' errors (docs/RESULTS.md,
"The motion inside the epoch"). Here that is modelled instead of ignored:

- each reference plane's error is a nuisance unknown, ``(dn, dd) = P_j L_j z_j`` with
  ``z_j ~ N(0, I_3)``: ``P_j`` maps the normal's tangent coordinates (two, about a basis
  orthogonal to ``n_j``) and the offset to ``(n, d)``, ``L_j`` the Cholesky factor of the
  plane's fit covariance in those coordinates (:attr:`Plane.covariance`) plus, when the
  plane has a deskewing Jacobian, the change a twist off by the run's twist change gives;
  marginalising it makes the residuals of one plane's points correlated, so a tilt or
  offset the plane's own fit leaves open is not read as motion;
- the correction's time-varying coefficients (degree >= 1: how the motion inside the
  epoch departs from the curve through the poses) get a zero-mean prior with the run's
  twist change over half the epoch's span (per axis, the rms change of the angular rate
  and of the velocity between successive measured steps, over sqrt 3, the model of
  :mod:`planodom.odometry.twist_sigma`): the curve is the constant-twist prediction, and
  it is off by what the twist changes over an epoch; the constant terms (the epoch's pose
  against the reference, which the odometry measures anyway) keep the fixed priors.

The solve is Gauss-Newton with Cauchy weights (iteratively reweighted) on the point
residuals only (scipy's ``least_squares`` robustifies the prior rows too); a few dozen
unknowns, so the normal equations are solved directly.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.geometry import Plane, invert_transform
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.twist_sigma import step_sigma
from planodom.rotvec import rotation_matrices
from planodom.se3 import se3_log


def twist_change(
    times: np.ndarray, poses: np.ndarray, results: Sequence[RelativePose | None]
) -> np.ndarray:
    """(2,) rms change of the angular rate (rad/s) and of the velocity (m/s) from one
    epoch to the next: the differences of successive twists of OK steps, less the part
    their own errors explain (:func:`.twist_sigma.step_sigma`), as
    :class:`.twist_sigma.TwistUncertainty` measures it online; NaN when no two successive
    steps are OK.

    Args:
        times: (N,) s. poses: (N, 4, 4) ``T_world_base``. results: per epoch its step.
    """
    changes = []
    previous: tuple[np.ndarray, np.ndarray] | None = None
    for k in range(1, len(times)):
        r, dt = results[k], float(times[k] - times[k - 1])
        if r is None or r.status is not Status.OK or dt <= 0:
            previous = None
            continue
        twist = se3_log(invert_transform(poses[k - 1]) @ poses[k]) / dt
        var = step_sigma(r, dt) ** 2
        if previous is not None and np.isfinite(var).all():
            d = twist - previous[0]
            sq = np.array([d[:3] @ d[:3], d[3:] @ d[3:]]) - var - previous[1]
            changes.append(np.maximum(sq, 0.0))
        previous = (twist, var) if np.isfinite(var).all() else None
    if not changes:
        return np.full(2, np.nan)
    return np.sqrt(np.mean(changes, axis=0))


def tangent_basis(n: np.ndarray) -> np.ndarray:
    """(3, 2) an orthonormal basis of the plane orthogonal to the unit vector ``n``."""
    a = np.eye(3)[int(np.argmin(np.abs(n)))]
    e1 = np.cross(n, a)
    e1 /= np.linalg.norm(e1)
    return np.c_[e1, np.cross(n, e1)]


def plane_error_factor(plane: Plane, motion_change: np.ndarray) -> np.ndarray | None:
    """(4, 3) ``F`` with ``(dn, dd) = F z``, ``z ~ N(0, I_3)``: the plane's error (module
    docstring); None when its covariance is unknown. ``motion_change``: (6,) per-axis
    sigmas of the twist error over the epoch's span (rad, m), for the deskewing Jacobian."""
    if plane.covariance is None:
        return None
    P = np.zeros((4, 3))
    P[:3, :2] = tangent_basis(plane.normal)
    P[3, 2] = 1.0
    cov = P.T @ plane.covariance @ P
    if plane.deskew_jacobian is not None:
        J = P.T @ plane.deskew_jacobian * motion_change
        cov = cov + J @ J.T
    cov = 0.5 * (cov + cov.T) + 1e-18 * np.eye(3)
    w, V = np.linalg.eigh(cov)
    return P @ (V * np.sqrt(np.maximum(w, 0.0)))


def map_solve(
    p: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    plane_index: np.ndarray,
    planes: Sequence[Plane],
    factors: Sequence[np.ndarray | None],
    B: np.ndarray,
    sigma: np.ndarray,
    scale: float,
    iterations: int = 15,
) -> tuple[np.ndarray, np.ndarray]:
    """The coefficients (P,) minimising the Cauchy-weighted point-to-plane residuals with
    the planes' errors as nuisance unknowns and the coefficients' zero-mean prior
    ``sigma`` (P,) (module docstring), and the point residuals (N,) m at the solution.

    Args:
        p: (N, 3) points, each in the base frame of its own time. R, t: (N, 3, 3), (N, 3)
            the curve's transform of each into the reference frame. plane_index: (N,)
            index into ``planes`` (the reference planes) and ``factors`` (their
            :func:`plane_error_factor`, None: exact). B: (N, 6, P) ``(w, v) = B x``.
        scale: the residuals' sigma (m); Cauchy at three of it.
    """
    P, n_pts = B.shape[2], len(p)
    used = np.unique(plane_index)
    with_error = [j for j in used if factors[j] is not None]
    col = {j: P + 3 * i for i, j in enumerate(with_error)}
    size = P + 3 * len(with_error)
    n0 = np.array([pl.normal for pl in planes])[plane_index]
    d0 = np.array([pl.offset for pl in planes])[plane_index]
    prior = np.r_[1.0 / sigma**2, np.ones(size - P)]
    x = np.zeros(size)
    res = np.zeros(n_pts)
    for _ in range(iterations):
        dn, dd = np.zeros((n_pts, 3)), np.zeros(n_pts)
        for j in with_error:
            m = plane_index == j
            delta = factors[j] @ x[col[j] : col[j] + 3]
            dn[m], dd[m] = delta[:3], delta[3]
        n, d = n0 + dn, d0 + dd
        wv = np.einsum("nkp,p->nk", B, x[:P])
        Rc = rotation_matrices(wv[:, :3])
        q = np.einsum("nij,nj->ni", Rc, p) + wv[:, 3:]
        y = np.einsum("nij,nj->ni", R, q) + t
        res = np.einsum("ni,ni->n", n, y) + d
        u = np.einsum("nij,ni->nj", R, n)  # the normal in the frame of the point's time
        uc = np.einsum("nij,ni->nj", Rc, u)  # Exp(w)^T u
        J = np.zeros((n_pts, size))
        J[:, :P] = np.einsum("nk,nkp->np", np.c_[np.cross(p, uc), u], B)
        for j in with_error:
            m = plane_index == j
            J[m, col[j] : col[j] + 3] = np.c_[y[m], np.ones(m.sum())] @ factors[j]
        w = 1.0 / (1.0 + (res / (3.0 * scale)) ** 2)  # Cauchy (IRLS)
        H = (J * w[:, None]).T @ J / scale**2 + np.diag(prior)
        g = J.T @ (w * res) / scale**2 + prior * x
        step = np.linalg.solve(H, -g)
        x = x + step
        if np.max(np.abs(step[:P]) * np.sqrt(prior[:P])) < 1e-6:
            break
    return x[:P], res
