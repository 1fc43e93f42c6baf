"""The yaw of a bridged step, from its walls (``odometry.wall_yaw``).

A step whose planes share no associated non-parallel pair is unresolved and bridged by
constant velocity (:func:`planodom.odometry.bridge_trend.bridge`). But a vertical wall's
normal turns with the heading, so walls of one direction (the two of a corridor) measure
the yaw though nothing measures the rotation about their normal. Under the bridged
``T_ref_k``, SDA associates the planes (:func:`planodom.association.strict_association`,
translations within ``association.prior_translation_m``, normals first within
``association.prior_rotation_deg + strict_normal_deg``: the prior's rotation may be off
by its bound, then within ``strict_normal_deg`` of the corrected rotation); each
association ``(i, j)`` gives the angle about the vertical from the horizontal part
``h_c`` of the current normal rotated by the bridge to the horizontal part ``h_p`` of the
reference's. Its variance is the two normals' variances (the trace of their fit
covariances' normal blocks, plus ``odometry.refine_normal_floor_deg`` squared each) over
``|h_p| |h_c|``: a level plane (the ground) has no horizontal part and no weight. The
correction is the inverse-variance mean, applied about the reference's vertical:
``R = Rz(delta) R_bridge``. Roll, pitch and the translation stay the bridge's, the step
stays unresolved (its rate is not measured and is not carried into the prediction).
"""

from __future__ import annotations

import numpy as np

from planodom.association import strict_association
from planodom.config import PlanodomConfig
from planodom.geometry import make_transform
from planodom.planes import PlaneSet


def normal_variances(planes: PlaneSet, idx: np.ndarray) -> np.ndarray:
    """(L,) the trace of the normal block of planes ``idx``'s covariances (rad^2); 0 where
    unknown (not finite)."""
    cov = planes.covariances[idx]
    var = np.trace(cov[:, :3, :3], axis1=1, axis2=2)
    return np.where(np.isfinite(var), var, 0.0)


def wall_yaw(
    prev: PlaneSet, curr: PlaneSet, prior: np.ndarray, cfg: PlanodomConfig, widen: float = 0.0
) -> tuple[float, float] | None:
    """(yaw correction rad, its variance rad^2) of ``prior`` (4, 4) from the planes SDA
    associates under it, its normal gate widened by ``widen`` deg (module docstring); None
    when none is associated or none has a horizontal normal part."""
    R0, t0 = prior[:3, :3], prior[:3, 3]
    acfg = cfg.association
    gate = acfg.model_copy(update={"strict_normal_deg": acfg.strict_normal_deg + widen})
    ij = strict_association(prev, curr, R0, gate, t0, acfg.prior_translation_m)
    if not len(ij):
        return None
    hp = prev.normals[ij[:, 0], :2]
    hc = (curr.normals[ij[:, 1]] @ R0.T)[:, :2]
    angle = np.arctan2(hc[:, 0] * hp[:, 1] - hc[:, 1] * hp[:, 0], np.sum(hc * hp, axis=1))
    floor = np.radians(cfg.odometry.refine_normal_floor_deg) ** 2
    var = normal_variances(prev, ij[:, 0]) + normal_variances(curr, ij[:, 1]) + 2 * floor
    w = np.linalg.norm(hp, axis=1) * np.linalg.norm(hc, axis=1) / var
    if not w.sum() > 0:
        return None
    return float(w @ angle / w.sum()), float(1.0 / w.sum())


def yaw_rotation(angle: float) -> np.ndarray:
    """(3, 3) the rotation by ``angle`` rad about z."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def walls_yawed(T: np.ndarray, prev: PlaneSet, curr: PlaneSet, cfg: PlanodomConfig) -> np.ndarray:
    """(4, 4) the bridged ``T`` (``T_ref_k``) with its yaw from the walls of ``prev`` (the
    reference's planes) and ``curr`` (the epoch's) with ``odometry.wall_yaw``, in two
    passes (module docstring); ``T`` itself when off or when a pass associates no wall."""
    if not cfg.odometry.wall_yaw:
        return T
    out = T
    for widen in (cfg.association.prior_rotation_deg, 0.0):
        yaw = wall_yaw(prev, curr, out, cfg, widen)
        if yaw is None:
            return T
        out = make_transform(yaw_rotation(yaw[0]) @ out[:3, :3], T[:3, 3])
    return out
