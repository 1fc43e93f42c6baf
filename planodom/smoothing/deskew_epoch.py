"""Each epoch's deskewing error sized by what its own planes fix of its twist's rotation
(``smoothing.sandwich_motion_scale`` "epoch").

The sandwich covariances (:mod:`.sandwich`) take each epoch's deskewing error ``e_k`` (the
twist its points were deskewed with less the true one, times their span: rad, m) to have
a covariance ``Q_k``. By default ("run", :mod:`.deskew_scale`) ``Q_k`` is the run's local
changes of motion scaled per axis by one factor for the run, estimated by moments of
``d_k``, the deskewing twist less the odometry's step over the points' times. Against the
truth that is not what the coplanar deskewing gets wrong (docs/RESULTS.md, NEESRUN): on
the 2D-rig laps 38 at 6 mm and 144 at 2 cm ``d_k`` is uncorrelated with the epochs' true
deskewing errors (|corr| <= 0.18 on every axis) and sized like the steps' errors (median
|d| 74-230 urad in rotation, the true errors' 14-62 urad): the moments measure the steps,
not the deskewing, and most epochs' ``Q_k`` is several times their error (38 at 6 mm: median
``e^T (Q + (A^T A)^-1)^-1 e`` 0.29 per dof, 47 % of the epochs below chi2's 5 % quantile;
the first epoch 0.04).

The batch's odometry deskews each epoch with the twist fit to its own planes' points
(``smoothing.odometry_deskew_twist`` "coplanar", :mod:`planodom.odometry.coplanar`): a
Gauss-Newton fit with the predicted twist as its prior. So the error is that fit's: the
prior's error, narrowed by what the planes' coplanarity fixes. Here, per epoch,

    Q_k = (P_k^-1 + R (I_k / COPLANAR_RATIO) R)^-1,   I_k = sum_planes J^T C^+ J,

``J`` (4, 6) each plane's ``deskew_jacobian`` and ``C`` (4, 4) its fit covariance: ``I_k``
is the information the epoch's planes hold about a rigid displacement by ``e_k``, and the
coplanarity sees the twist through the spread of the points' times about their mean where
the planes' positions see it through the mean, a ratio ``mean(t)^2 / var(t)`` = 3 for times
spread uniformly from the reference time and independent of where the points lie
(:data:`COPLANAR_RATIO`; derived, not fitted; tests/smoothing/test_deskew_epoch.py checks
it against the exact information of such a fit within 15 %). ``R`` keeps its rotation
block only: a scanner's times follow where its points lie (a 2D rig's sweeps, a lidar's
azimuth), and a translation error's displacement, ``t v``, is then affine along a plane and
taken by the plane's own tilt: on planes swept along one direction the fit's exact
information about the translation is 1 % of ``I_k / 3``, about the rotation 0.6-1.5 times
it (the same test). The translation keeps its prior.
``P_k`` is the prior's error: for every epoch but the first the "run" value (the twist
predicted from the steps before, off by the change of motion and the steps' error, which
is what ``d_k``'s moments do measure); the first epoch has no twist before it, it is
deskewed again with its first step's twist as the prior (docs/RESULTS.md, FIRSTEPOCH), so
its ``P_0`` is that step's declared covariance over its span
(:func:`.first_epoch_noise.first_step_covariance`; the "run" value where that step is
unknown or unmeasured). An epoch without planes keeps ``P_k``; one whose ``P_k`` is zero
(taken at one instant) stays zero.

Off: sized so, the good lap 38 at 6 mm is right epoch by epoch against the truth, but at
2 cm the true errors are 3-12 times what the planes' coplanarity allows (a constant twist
cannot follow the motion within the epoch), and over 23 decision-lap runs the laps inside
the NEES interval fall from 7 to 4 of 14 at 2 cm and 5 to 0 of 9 at 6 mm
(docs/RESULTS.md, NEESRUN).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

import numpy as np

from planodom.geometry import Plane
from planodom.odometry.relative import RelativePose
from planodom.smoothing.first_epoch_noise import first_step_covariance

#: ``mean(t)^2 / var(t)`` of points' times spread uniformly over ``[0, span]``: the
#: coplanarity's information about the twist against the planes' positions' (module
#: docstring).
COPLANAR_RATIO = 3.0


def plane_information(planes: Iterable[Plane]) -> np.ndarray:
    """(6, 6) ``sum J^T C^+ J`` over ``planes`` with both a ``deskew_jacobian`` ``J`` (4, 6)
    and a ``covariance`` ``C`` (4, 4; its pseudo-inverse: rank 3) (per (rad, m)^2)."""
    info = np.zeros((6, 6))
    for p in planes:
        if p.deskew_jacobian is None or p.covariance is None:
            continue
        C = np.asarray(p.covariance, dtype=float)
        if not np.all(np.isfinite(C)):
            continue
        J = np.asarray(p.deskew_jacobian, dtype=float)
        info += J.T @ np.linalg.pinv(C, rcond=1e-9, hermitian=True) @ J
    return info


def fused(prior: np.ndarray, information: np.ndarray) -> np.ndarray:
    """(6, 6) ``(prior^-1 + information)^-1`` (both (6, 6), symmetric, positive
    semi-definite; a zero prior variance stays zero, a zero information keeps the prior),
    as ``S (I + S information S)^-1 S`` with ``S`` the prior's square root."""
    w, V = np.linalg.eigh(np.asarray(prior, dtype=float))
    S = (V * np.sqrt(np.maximum(w, 0.0))) @ V.T
    out = S @ np.linalg.solve(np.eye(6) + S @ information @ S, S)
    return 0.5 * (out + out.T)


def epoch_sizes(
    prior: np.ndarray,
    planes: Mapping[int, tuple[int, Plane]],
    relative_poses: Sequence[RelativePose],
) -> np.ndarray:
    """(E, 6, 6) ``Q_k`` of the module docstring (rad^2, m^2).

    Args:
        prior: (E, 6, 6) ``P_k``, the "run" sizes (:func:`.deskew_scale.scaled_motion_change`).
        planes: the plane factors' epochs and planes (any key).
        relative_poses: the run's (the first step's covariance for ``P_0``).
    """
    P = np.array(prior, dtype=float, copy=True)
    by_epoch: dict[int, dict[int, Plane]] = {}  # a plane in several factors counts once
    for epoch, plane in planes.values():
        by_epoch.setdefault(epoch, {})[id(plane)] = plane
    first = first_step_covariance(relative_poses)
    if len(P) and first is not None and np.any(P[0]):
        P[0] = first
    out = np.zeros_like(P)
    for k in range(len(P)):
        if np.any(P[k]):
            info = plane_information(by_epoch.get(k, {}).values()) / COPLANAR_RATIO
            info[3:, :] = info[:, 3:] = 0.0  # the rotation block (module docstring)
            out[k] = fused(P[k], info)
    return out
