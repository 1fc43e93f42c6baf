"""The rotation of a bridged step from the normals it shares with its reference
(``odometry.bridge_normals``).

A step whose planes share no associated non-parallel pair is unresolved and bridged by
constant velocity (:func:`planodom.odometry.bridge_trend.bridge`). But the planes it does
share measure part of the rotation: the two walls of a corridor (one direction) turn
with the heading and tilt with a roll about the corridor; only the rotation about their
common normal is not seen. Under the bridged ``T_ref_k``, SDA associates the planes
(:func:`planodom.association.strict_association`, translations within
``association.prior_translation_m``, normals first within ``association.
prior_rotation_deg + strict_normal_deg``: the bridge's rotation may be off by the
prior's bound; then twice within ``strict_normal_deg`` of the corrected rotation). The
correction ``delta`` (a rotation vector in the reference's frame, ``R = exp(delta)
R_bridge``) minimises ``sum_i w_i |n_p,i - exp(delta) m_i|^2`` to first order, ``m_i``
the current normal rotated by the bridge: ``A delta = b`` with ``A = sum_i w_i (I - m_i
m_i^T)`` and ``b = sum_i w_i m_i x n_p,i``, ``w_i`` the inverse of the two normals'
variances (the trace of their fit covariances' normal blocks, plus
``odometry.refine_normal_floor_deg`` squared each). ``A``'s directions whose eigenvalue is
under ``sin^2(association.parallel_angle_deg)`` times its largest are not observed (the
rotation about one family's normal): ``delta`` has no part along them, and they keep the
bridge's rotation. The translation and the step's status stay the bridge's (its twist
is what the odometry makes of the bridged step).

``weighed`` takes the bridge as a measurement too: its rotation error, per axis of
variance ``v`` (rad^2; :meth:`planodom.odometry.twist_sigma.TwistUncertainty.
bridged_rotation_sigma`, the held rate's sigma summed over the bridged steps), is a prior
on ``delta``, and each pass solves the combined normal equations ``(A + I/v) delta = b +
r/v`` in the observed directions, ``r`` the bridge's rotation relative to the pass's
(0 in the first; Gauss-Newton with the prior held at the bridge): a short bridge of a
well-measured rate keeps most of its rotation, a long one held through a turn's end
takes the normals'. ``v`` = 0 gives the bridge, ``v`` -> inf ``true``'s rotation.
"""

from __future__ import annotations

import numpy as np

from planodom.association import strict_association
from planodom.config import PlanodomConfig
from planodom.geometry import make_transform
from planodom.planes import PlaneSet
from planodom.rotvec import rotation_matrices, rotation_vectors


def normal_variances(planes: PlaneSet, idx: np.ndarray) -> np.ndarray:
    """(L,) the trace of the normal block of planes ``idx``'s covariances (rad^2); 0 where
    unknown (not finite)."""
    cov = planes.covariances[idx]
    var = np.trace(cov[:, :3, :3], axis1=1, axis2=2)
    return np.where(np.isfinite(var), var, 0.0)


def normals_rotation(
    prev: PlaneSet,
    curr: PlaneSet,
    T: np.ndarray,
    cfg: PlanodomConfig,
    widen: float = 0.0,
    prior: tuple[np.ndarray, float] | None = None,
) -> np.ndarray | None:
    """(3,) the rotation vector (rad, reference frame) that corrects ``T``'s rotation by
    the normals SDA associates under ``T`` (4, 4), its normal gate widened by ``widen``
    deg (module docstring); None when none is associated. With ``prior`` (the bridge's
    rotation (3, 3) and its variance per axis, rad^2) the combined estimate of
    ``weighed`` (module docstring)."""
    R0, t0 = T[:3, :3], T[:3, 3]
    acfg = cfg.association
    gate = acfg.model_copy(update={"strict_normal_deg": acfg.strict_normal_deg + widen})
    ij = strict_association(prev, curr, R0, gate, t0, acfg.prior_translation_m)
    if not len(ij):
        return None
    n_p, m = prev.normals[ij[:, 0]], curr.normals[ij[:, 1]] @ R0.T
    floor = np.radians(cfg.odometry.refine_normal_floor_deg) ** 2
    w = 1.0 / (normal_variances(prev, ij[:, 0]) + normal_variances(curr, ij[:, 1]) + 2 * floor)
    A = np.einsum("i,ij,ik->jk", w, m, m)
    A = w.sum() * np.eye(3) - A
    b = np.einsum("i,ij->j", w, np.cross(m, n_p))
    vals, vecs = np.linalg.eigh(A)
    seen = vals > np.sin(np.radians(acfg.parallel_angle_deg)) ** 2 * vals[-1]
    V = vecs[:, seen]
    if prior is None:
        return V @ ((V.T @ b) / vals[seen])
    r = rotation_vectors((prior[0] @ R0.T)[None])[0]  # the bridge, from T's rotation
    if not prior[1] > 0:  # an exact bridge: back to it in the observed directions
        return V @ (V.T @ r)
    return V @ ((V.T @ (b + r / prior[1])) / (vals[seen] + 1.0 / prior[1]))


def normals_bridged(
    T: np.ndarray,
    prev: PlaneSet,
    curr: PlaneSet,
    cfg: PlanodomConfig,
    variance: float | None = None,
) -> np.ndarray:
    """(4, 4) the bridged ``T`` (``T_ref_k``) with its rotation corrected by the normals
    of ``prev`` (the reference's planes) and ``curr`` (the epoch's) when
    ``odometry.bridge_normals`` is on, in three passes (module docstring); ``T`` itself
    when off or when a pass associates nothing. ``variance`` (rad^2 per axis; None:
    unknown, the bridge is given no weight): the bridge's rotation error, weighed
    against the normals with ``weighed``."""
    if not cfg.odometry.bridge_normals:
        return T
    weighed = cfg.odometry.bridge_normals == "weighed" and variance is not None
    prior = (T[:3, :3], float(variance)) if weighed and variance is not None else None
    out = T
    for widen in (cfg.association.prior_rotation_deg, 0.0, 0.0):
        delta = normals_rotation(prev, curr, out, cfg, widen, prior)
        if delta is None:
            return T
        out = make_transform(rotation_matrices(delta[None])[0] @ out[:3, :3], T[:3, 3])
    return out
