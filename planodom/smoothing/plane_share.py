"""Each plane factor's own share of its epoch's deskewing error in its noise model, and the
sandwich without it (``smoothing.sandwich_plane_share`` "own", batch).

The sandwich (:mod:`.sandwich`) takes the whitened measurements' error as ``I + G Q G^T``:
per epoch k one deskewing error ``dxi_k ~ N(0, Q_k)`` moves every plane of the epoch
through its ``deskew_jacobian``. Its block on one plane factor, ``g_i Q_k g_i^T``, is that
plane's own share; the blocks between two planes of one epoch are what they share. With
"own" the noise model of plane factor i holds ``C_i + J_i Q_k J_i^T`` (:func:`own_share`;
``C_i`` the fit's covariance), so a plane the deskewing moves much weighs less in the
estimate. The modelled error itself does not change (``C + J Q J^T`` over all planes,
unwhitened): in the new whitening the sandwich's ``S`` is ``G Q G^T`` less the own
blocks. The sandwich's extra term is linear in ``S``, so the own blocks are a second
term with one column per plane factor (:func:`own_columns`), subtracted
(:func:`less_own`): the same selected inversion (or dense path) run once more.

Where a global landmark's factor makes its normal block isotropic
(:func:`factors.planes.plane_noise`) the noise model holds more than ``C_i + J_i Q_k
J_i^T`` in the normal; the subtracted block is the one the factor's whitening gives, so
the sandwich then models a little more than the default (never less).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import gtsam
import numpy as np

from planodom.geometry import Plane
from planodom.smoothing.error_maps import ErrorMaps, map_terms

if TYPE_CHECKING:
    from planodom.smoothing.sandwich import SandwichMarginals


def own_share(plane: Plane, q: np.ndarray) -> np.ndarray:
    """(3, 3) ``J q J^T``: the plane's share of its epoch's deskewing error ``q`` (6, 6) in
    OrientedPlane3 tangent coordinates (Unit3 basis (2), d), ``J`` its ``deskew_jacobian``
    in them (as :func:`.noise.plane_covariance`'s change of motion); zero without one."""
    if plane.deskew_jacobian is None or not np.any(q):
        return np.zeros((3, 3))
    P = np.zeros((4, 3))  # (n, d) -> tangent, as plane_tangent_covariance
    P[:3, :2] = np.asarray(gtsam.Unit3(np.asarray(plane.normal, dtype=float)).basis())
    P[3, 2] = 1.0
    J = P.T @ np.asarray(plane.deskew_jacobian, dtype=float)
    return J @ np.asarray(q, dtype=float) @ J.T


def own_columns(plane_maps: ErrorMaps, Q: np.ndarray) -> tuple[dict, np.ndarray]:
    """The own blocks as sandwich terms: factor i with map ``(k, g)`` gets a column of its
    own (j, in the order of ``plane_maps``) whose covariance is ``Q[k]``; returns the
    maps (i -> (j, g)) and the (n, 6, 6) covariances of the columns."""
    maps: dict[int, tuple[int, np.ndarray]] = {}
    sizes: list[np.ndarray] = []
    for i in plane_maps:
        for k, g in map_terms(plane_maps, i):  # one term: a plane factor's own epoch
            maps[i] = (len(sizes), g)
            sizes.append(Q[k])
    return maps, np.array(sizes, dtype=float).reshape(-1, 6, 6)


def less_own(out: SandwichMarginals, own: SandwichMarginals) -> SandwichMarginals:
    """``out``'s covariances less the extra term of ``own`` (the same graph's sandwich of
    the own blocks alone: its covariances less its fitted ones)."""
    return replace(out, covariances=out.covariances - (own.covariances - own.fitted))
