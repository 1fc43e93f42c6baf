"""A fixed-lag smoother's marginal factor (a Hessian) as a Jacobian factor, for QR.

iSAM2 with Cholesky keeps the marginals of what it marginalised as
``LinearContainerFactor`` s holding a ``HessianFactor`` (information form). QR eliminates
Jacobian factors only, so a smoother rebuilt with QR from such a state (the windowed
smoother's Cholesky -> QR fallback) converts each marginal by a Cholesky of its
information matrix alone, which can fail where the marginal leaves a direction
unobserved that other factors fix: an anchored plane landmark's gauge (anchor and
plane turned together, fixed by the anchor's own prior, not part of the marginal). Its
eigenvalues there are zero but come out of the marginalisation as round-off of either
sign, about ``eps * max eigenvalue``: on urban-canyon at 0 mm (plane factors at their
floors, information to 9e13) down to -0.03, and gtsam's conversion (a Cholesky that
takes zero pivots but not negative ones) refused it: the fixed-lag smoother stopped at
epoch 395. Here the information matrix is split by its eigendecomposition instead, the
directions within round-off of zero dropped (a rank-deficient Jacobian, which QR
takes); nothing is added.

A marginal is a Schur complement of positive semi-definite information, so it is
indefinite only by round-off; but that round-off is of the size of the information
eliminated into it (``eps`` times the stiffest factors of the marginalised variables), not
of the marginal's own largest eigenvalue, which can be orders of magnitude smaller
(WINDCRASH: worlds 6 and 10 of the 2D-rig laps at 6 mm, eigenvalues down to -2.3e-5 and
-2.2e-4 against ``10 n eps max w`` = 1.6e-5 and 4.5e-5). Such a marginal is not refused:
its most negative eigenvalue measures the round-off, every direction within it of zero
(either sign) is dropped as unobserved, and the split reports it
(:attr:`InformationSplit.indefinite`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import gtsam
import numpy as np

#: Eigenvalues within this many machine epsilons of the largest (times the dimension) are
#: round-off of zero (the marginal does not observe their directions).
ROUND_OFF_EPS = 10.0


class InformationSplit(NamedTuple):
    """An information matrix as a Jacobian on the directions it observes.

    Attributes:
        A: (r, n) with ``A.T @ A`` the information on the kept directions.
        b: (r,) with ``A.T @ b`` the information vector on them.
        indefinite: the most negative eigenvalue relative to the largest (``-w_min /
            w_max`` > 0) where it was negative beyond ``eps * n * machine epsilon``
            (round-off of the information eliminated into a marginal; its directions and
            every one within it of zero dropped), else 0.
    """

    A: np.ndarray
    b: np.ndarray
    indefinite: float


def split_information(G: np.ndarray, g: np.ndarray, eps: float = ROUND_OFF_EPS) -> InformationSplit:
    """``A, b`` with ``A.T @ A = G`` and ``A.T @ b = g`` on the directions ``G`` observes.

    Args:
        G: (n, n) symmetric information matrix (positive semi-definite up to round-off).
        g: (n,) information vector (the error is ``x G x / 2 - g x + const``).
        eps: eigenvalues below ``eps * n * machine epsilon * max eigenvalue`` in absolute
            value are dropped as round-off of zero; where the smallest eigenvalue is more
            negative than that, it is the round-off's size, and every eigenvalue not
            above its magnitude is dropped (``indefinite`` reports it).

    Returns:
        The split; ``A`` (r, n) and ``b`` (r,), r the number of eigenvalues kept.
    """
    G = 0.5 * (G + G.T)
    w, V = np.linalg.eigh(G)
    top = max(float(w[-1]), 0.0)
    tol = eps * G.shape[0] * np.finfo(float).eps * top
    indefinite = 0.0
    if w[0] < -tol:  # the round-off is larger than tol: at least |w[0]|
        tol = -float(w[0])
        indefinite = tol / top if top > 0.0 else float("inf")
    keep = w > tol
    root = np.sqrt(w[keep])
    A = root[:, None] * V[:, keep].T
    b = (V[:, keep].T @ g) / root
    return InformationSplit(A, b, indefinite)


def jacobian_from_information(
    G: np.ndarray, g: np.ndarray, eps: float = ROUND_OFF_EPS
) -> tuple[np.ndarray, np.ndarray]:
    """``A`` (r, n), ``b`` (r,) of :func:`split_information` (see there)."""
    split = split_information(G, g, eps)
    return split.A, split.b


def _is_plane(values: gtsam.Values, key: int) -> bool:
    try:
        values.atOrientedPlane3(key)
    except RuntimeError:
        return False
    return True


def _local(x0: gtsam.Values, values: gtsam.Values, key: int, plane: bool) -> np.ndarray:
    if plane:
        return np.asarray(x0.atOrientedPlane3(key).localCoordinates(values.atOrientedPlane3(key)))
    return np.asarray(x0.atPose3(key).localCoordinates(values.atPose3(key)))


def jacobian_marginal(
    factor: gtsam.LinearContainerFactor,
    point: gtsam.Values,
    eps: float = ROUND_OFF_EPS,
    indefinite: list[float] | None = None,
) -> gtsam.CustomFactor:
    """The marginal ``factor`` as a Jacobian factor on the same keys (Pose3 or
    OrientedPlane3 variables), linearised at ``point`` (holding its keys).

    Like the container it is linear in the local coordinates ``point.localCoordinates(x)``
    (its Jacobian fixed); error ``A delta - b``, unit noise, ``A, b`` from
    :func:`split_information` of the factor's information at ``point``. Where that
    information is indefinite beyond round-off, its :attr:`InformationSplit.indefinite`
    is appended to ``indefinite`` (if given).
    """
    keys: Sequence[int] = list(factor.keys())
    hessian = gtsam.HessianFactor(factor.linearize(point))
    info = np.asarray(hessian.information())
    g = np.asarray(hessian.linearTerm()).ravel()
    A, b, negative = split_information(info, g, eps)
    if negative > 0.0 and indefinite is not None:
        indefinite.append(negative)
    planes = [_is_plane(point, key) for key in keys]
    dims = [3 if p else 6 for p in planes]
    starts = np.concatenate([[0], np.cumsum(dims)])
    blocks = [A[:, starts[i] : starts[i + 1]] for i in range(len(keys))]
    x0 = gtsam.Values()
    for key, plane in zip(keys, planes, strict=True):
        x0.insert(key, point.atOrientedPlane3(key) if plane else point.atPose3(key))
    pairs = list(zip(keys, planes, strict=True))

    def error(
        this: gtsam.CustomFactor, values: gtsam.Values, H: list[np.ndarray] | None
    ) -> np.ndarray:
        delta = np.concatenate([_local(x0, values, key, plane) for key, plane in pairs])
        if H is not None:
            for i, block in enumerate(blocks):
                H[i] = block
        return A @ delta - b

    noise = gtsam.noiseModel.Unit.Create(A.shape[0])
    return gtsam.CustomFactor(noise, list(keys), error)
