"""Both epochs' deskewing errors in the steps' stated covariances
(``odometry.stated_deskew_noise: shared``).

A step ``T_prev_curr`` is solved from the planes of epochs prev and curr. Each epoch's
points were deskewed with a twist off by some ``dxi`` (rad/s, m/s), which moves every
plane of that epoch by its own ``Plane.deskew_jacobian`` ``D`` (4, 6) times the epoch's
span: one error shared by all the epoch's planes, which the planes' fit covariances (and
so the step's propagated covariance) leave out. Its first-order effect on the step is
``M_a`` (``M_b``) (6, 6), the change of the step (right tangent) fitted by weighted least
squares to the step's associated plane pairs when epoch a's (b's) planes move
(:func:`planodom.smoothing.relative_deskew.pair_fit_changes`, as NEES6's maps). With each
epoch's twist error independent, of covariance ``Q_k = span_k^2 Sigma``, the step's
error gains

    A (M_a Q_a M_a^T + M_b Q_b M_b^T) A^T

in (rotation vector, x, y) of frame prev (``A`` (5, 6): the right tangent's rotation,
and its translation turned into frame prev), mapped to the stated (roll, pitch, yaw, x,
y) by the inverse of :func:`planodom.smoothing.noise.rpy_to_rotation_vector`.

``Sigma``: the run's rms change of the twist (``se3_log`` of a step over its interval)
between successive OK steps, noise included, per rotation and translation block, as
``odometry.plane_deskew_noise: change`` sizes it (root of a trace, ``sigma^2 / 3`` per
axis: :func:`planodom.odometry.plane_deskew.twist_covariance`). A run-wide size, so it is
applied after the run: the estimate is not touched. Only the stated covariances change.

Epochs add nothing when they were not deskewed (no recorded twist or times: the first
epoch, a scan taken at one instant), and a step whose epoch was extracted again later
(``OdometryRun.superseded``: its associations index planes no longer kept) keeps its
covariance (the smoothing estimates it again from the kept planes, and states it there).
Measured before it was built (docs/RESULTS.md, DESKEWCOV, the probe rows): on 2D-rig
worlds 140-158 the OK steps above chi2(5)'s 95 % quantile fell from 35 % to 2-4 %, the
estimate unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from planodom.geometry import Plane, rpy_from_rotation
from planodom.odometry.plane_deskew import twist_covariance
from planodom.odometry.relative import RelativePose, Status
from planodom.odometry.run import OdometryRun
from planodom.se3 import se3_log


def run_twist_change(results: Sequence[RelativePose | None], times: np.ndarray) -> np.ndarray:
    """(6, 6) ``Sigma`` of the module docstring (rad/s, m/s; rotation first): from the
    twists of OK steps ``k - 1 -> k`` (``results[k]``, ``times`` (E,) s), the rms of the
    differences of successive ones; zero without two successive OK steps."""
    twists: dict[int, np.ndarray] = {}
    for k, r in enumerate(results):
        if r is not None and r.status is Status.OK and r.curr == r.prev + 1 == k:
            dt = float(times[k] - times[k - 1])
            if dt > 0.0:
                twists[k] = se3_log(np.asarray(r.T_prev_curr, dtype=float)) / dt
    d = np.array([twists[k] - twists[k - 1] for k in twists if k - 1 in twists])
    if len(d) == 0:
        return np.zeros((6, 6))
    rate = float(np.sqrt(np.mean(np.sum(d[:, :3] ** 2, axis=1))))
    speed = float(np.sqrt(np.mean(np.sum(d[:, 3:] ** 2, axis=1))))
    return twist_covariance((rate, speed))


def epoch_deskew_covariances(
    results: Sequence[RelativePose | None], sigma: np.ndarray
) -> np.ndarray:
    """(E, 6, 6) ``Q_k = span_k^2 Sigma`` per epoch (rad, m over the epoch's span; zero
    for an epoch without a recorded deskewing twist and times), ``span_k`` the largest
    ``|t|`` of its points' times (``RelativePose.deskew_times``), the span the extraction
    divides the times by for ``Plane.deskew_jacobian``."""
    out = np.zeros((len(results), 6, 6))
    for k, r in enumerate(results):
        if r is None or r.deskew_twist is None or r.deskew_times is None:
            continue
        span = max(abs(float(r.deskew_times[0])), abs(float(r.deskew_times[1])))
        out[k] = span**2 * np.asarray(sigma, dtype=float)
    return out


def shared_term(
    rel: RelativePose,
    planes_prev: Sequence[Plane],
    planes_curr: Sequence[Plane],
    Q_prev: np.ndarray,
    Q_curr: np.ndarray,
) -> np.ndarray:
    """(5, 5) both epochs' deskewing error of ``rel`` in its stated (roll, pitch, yaw, x,
    y) coordinates (rad^2, rad m, m^2; module docstring); zero without associations or
    where neither end's planes carry a Jacobian."""
    from planodom.smoothing.noise import rpy_to_rotation_vector  # imports the odometry
    from planodom.smoothing.relative_deskew import pair_fit_changes

    out = np.zeros((5, 5))
    if rel.associations is None or len(rel.associations) == 0:
        return out
    T = np.asarray(rel.T_prev_curr, dtype=float)
    ends = pair_fit_changes(T, planes_prev, planes_curr, rel.associations)
    A = np.zeros((5, 6))
    A[:3, :3] = np.eye(3)
    A[3:, 3:] = T[:2, :3]  # the right tangent's translation in frame prev's x, y
    for M, Q in zip(ends, (Q_prev, Q_curr), strict=True):
        if M is not None and np.any(Q):
            AM = A @ M
            out += AM @ Q @ AM.T
    J = np.eye(5)
    J[:3, :3] = np.linalg.inv(rpy_to_rotation_vector(rpy_from_rotation(T[:3, :3])))
    out = J @ out @ J.T
    return 0.5 * (out + out.T)


def stated_relatives(
    relatives: Sequence[RelativePose],
    planes: Sequence[Sequence[Plane]],
    Q: np.ndarray,
    superseded: Sequence[int] = (),
) -> list[RelativePose]:
    """``relatives`` with :func:`shared_term` added to the covariance of each resolved one
    with a finite covariance (new objects; unresolved ones, those without a covariance and
    the results of ``superseded`` epochs, whose associations index planes no longer kept,
    unchanged). ``planes``: every
    epoch's planes the associations index; ``Q`` (E, 6, 6) :func:`epoch_deskew_covariances`."""
    skip = set(superseded)
    out = []
    for r in relatives:
        cov = None if r.covariance is None else np.asarray(r.covariance, dtype=float)
        if (
            r.status is Status.UNRESOLVED
            or cov is None
            or not np.all(np.isfinite(cov))
            or r.prev < 0
            or r.curr in skip
        ):
            out.append(r)
            continue
        term = shared_term(r, planes[r.prev], planes[r.curr], Q[r.prev], Q[r.curr])
        out.append(replace(r, covariance=cov.reshape(5, 5) + term) if np.any(term) else r)
    return out


def with_stated_deskew(run: OdometryRun) -> OdometryRun:
    """``run`` with every step's stated covariance holding both its epochs' deskewing
    error (:func:`stated_relatives`, sized by :func:`run_twist_change`); the poses, planes
    and everything else are the same objects."""
    sigma = run_twist_change(run.results, np.asarray(run.times, dtype=float))
    Q = epoch_deskew_covariances(run.results, sigma)
    kept = [r for r in run.results if r is not None]
    restated = iter(stated_relatives(kept, run.planes, Q, run.superseded))
    results = [None if r is None else next(restated) for r in run.results]
    return replace(run, results=results)
