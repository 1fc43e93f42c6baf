"""The deskewing error of an epoch's planes in their covariances (``odometry.plane_deskew_noise``).

An epoch's points are deskewed with a twist ``xi`` (rad/s, m/s) known to a sigma
(:mod:`planodom.odometry.twist_sigma`). A twist off by ``dxi`` moves a point seen ``t``
after the reference time by about ``t (dw x p + dv)``, and a plane fitted to the points
by ``D dxi span`` to first order, with ``D`` (4, 6) the fit's change per twist error over
the epoch's span (``Plane.deskew_jacobian``, :func:`planodom.extraction.planes.fit.
deskew_jacobian`, computed with the times over ``span = max |t|``, as the extraction
does). With ``Cov(dxi) = Sigma`` the plane's ``(n, d)`` covariance grows by
``span^2 D Sigma D^T``. The fit's own covariance sees only the range noise: on issue 11's
world 166 (docs/RESULTS.md, RANGE166) steps on walls tilted by a wrong twist stated a yaw
sigma of 0.14 deg for errors of 0.3-0.7 deg.

``Sigma``: the twist model gives one sigma for the angular rate and one for the velocity,
each the root of the trace of its 3 x 3 block, so ``sigma^2 / 3`` per axis
(:func:`twist_covariance`). The smoothing sizes the same Jacobians by the run's changes of
motion instead (:mod:`planodom.smoothing.deskew_noise`); here the twist the epoch was
actually deskewed with, and its own uncertainty, are known.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from planodom.geometry import Plane
from planodom.scan import Scan


def twist_covariance(sigma: tuple[float, float]) -> np.ndarray:
    """(6, 6) diagonal covariance of a twist error (rad/s, m/s; rotation first) whose
    angular rate and velocity sigmas ``sigma`` are roots of traces over three axes."""
    rate, speed = sigma
    return np.diag(np.repeat(np.array([rate, speed], dtype=float) ** 2 / 3.0, 3))


def epoch_span(scan: Scan) -> float:
    """The epoch's span ``max |t|`` (s) the extraction divides the times by for
    ``Plane.deskew_jacobian`` (:mod:`planodom.extraction.planes.builder`); 0 without times."""
    if scan.t is None or len(scan.t) == 0:
        return 0.0
    return float(np.max(np.abs(scan.t)))


def deskew_covariance(plane: Plane, span: float, cov_twist: np.ndarray) -> np.ndarray | None:
    """(4, 4) covariance of ``plane``'s ``(n, d)`` due to a deskewing twist error of
    covariance ``cov_twist`` (6, 6) (rad/s, m/s) over an epoch of ``span`` s:
    ``span^2 D cov_twist D^T`` with ``D`` its ``deskew_jacobian``; None without one."""
    if plane.deskew_jacobian is None:
        return None
    J = np.asarray(plane.deskew_jacobian, dtype=float) * span
    return J @ cov_twist @ J.T


def with_deskew_noise(
    planes: Sequence[Plane],
    scan: Scan,
    twist: np.ndarray | None,
    sigma: tuple[float, float] | None,
) -> list[Plane]:
    """``planes`` extracted from ``scan`` deskewed with ``twist`` (6,) of sigmas ``sigma``
    (rad/s, m/s), each with :func:`deskew_covariance` added to its covariance (new
    :class:`Plane` objects; the others unchanged). Unchanged (the same objects) when the
    scan was not deskewed (``twist`` or ``sigma`` None), was taken at one instant (span 0),
    or for a plane without a covariance or a Jacobian."""
    span = epoch_span(scan)
    if twist is None or sigma is None or span <= 0.0 or not np.all(np.isfinite(sigma)):
        return list(planes)
    cov_twist = twist_covariance(sigma)
    out = []
    for plane in planes:
        added = deskew_covariance(plane, span, cov_twist)
        if added is None or plane.covariance is None:
            out.append(plane)
        else:
            out.append(replace(plane, covariance=np.asarray(plane.covariance) + added))
    return out
