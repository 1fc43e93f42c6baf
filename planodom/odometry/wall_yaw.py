"""The yaw of a step without a non-parallel pair, from its walls (``odometry.wall_yaw``).

A step whose planes share no associated non-parallel pair (the lenient association's
pairs) is unresolved: its rotation is not measured in full. But a vertical wall's normal
turns with the heading, so the walls of one direction (the two of a corridor) measure
the yaw though nothing measures the rotation about their normal. With a prior
``T_prev_curr`` (the constant-velocity prediction), SDA associates the planes under it
(:func:`planodom.association.strict_association`: normals within
``association.strict_normal_deg``); each association ``(i, j)`` gives the angle about
the vertical from the horizontal part ``h_c`` of the current normal rotated by the prior
to the horizontal part ``h_p`` of the previous one. Its variance is the normals'
variances (the trace of their fit covariances' normal blocks, plus
``odometry.refine_normal_floor_deg`` squared each) over ``|h_p| |h_c|``: a level plane
(the ground) has no horizontal part and no weight. The yaw correction is the
inverse-variance mean, applied about the previous frame's vertical:
``R = Rz(delta) R_prior``. Roll and pitch stay the prior's (their variance the prior's
rotation bound squared, as an unresolved step's), the translation is refined under ``R``
as a degenerate step's, and the step is degenerate.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from planodom.angles import pose_floor, radians
from planodom.association import strict_association
from planodom.config import PlanodomConfig
from planodom.geometry import make_transform
from planodom.odometry.pass_bounds import PassBounds
from planodom.odometry.relative import RelativePose, SolverDiagnostics, Status
from planodom.planes import PlaneSet


def normal_variances(planes: PlaneSet, idx: np.ndarray) -> np.ndarray:
    """(L,) the trace of the normal block of planes ``idx``'s covariances (rad^2); 0 where
    unknown (not finite)."""
    cov = planes.covariances[idx]
    var = np.trace(cov[:, :3, :3], axis1=1, axis2=2)
    return np.where(np.isfinite(var), var, 0.0)


def wall_yaw(
    prev: PlaneSet, curr: PlaneSet, prior: np.ndarray, cfg: PlanodomConfig, bound: float
) -> tuple[float, float] | None:
    """(yaw correction rad, its variance rad^2) of ``prior`` (4, 4) from the planes SDA
    associates under it within ``bound`` m of its translation (module docstring); None
    when none is associated or none has a horizontal normal part."""
    R0, t0 = prior[:3, :3], prior[:3, 3]
    ij = strict_association(prev, curr, R0, cfg.association, t0, bound)
    if not len(ij):
        return None
    hp = prev.normals[ij[:, 0], :2]
    hc = (curr.normals[ij[:, 1]] @ R0.T)[:, :2]
    angle = np.arctan2(hc[:, 0] * hp[:, 1] - hc[:, 1] * hp[:, 0], np.sum(hc * hp, axis=1))
    floor = radians(cfg.odometry.refine_normal_floor_deg) ** 2
    var = normal_variances(prev, ij[:, 0]) + normal_variances(curr, ij[:, 1]) + 2 * floor
    w = np.linalg.norm(hp, axis=1) * np.linalg.norm(hc, axis=1) / var
    if not w.sum() > 0:
        return None
    return float(w @ angle / w.sum()), float(1.0 / w.sum())


def yaw_rotation(angle: float) -> np.ndarray:
    """(3, 3) the rotation by ``angle`` rad about z."""
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def no_pair_step(
    prev: PlaneSet,
    curr: PlaneSet,
    cfg: PlanodomConfig,
    prior: np.ndarray | None,
    bounds: PassBounds,
    info: SolverDiagnostics,
    bound_by_prior: bool,
    refine: Callable,
) -> RelativePose:
    """The solver's step without an associated pair: unresolved (the prior, or identity),
    or with ``odometry.wall_yaw`` and a prior that bounds the pass, degenerate with its
    yaw from the walls (module docstring). ``refine(prev, curr, R, t, measured, bounds,
    cfg)`` is the solver's refinement (``.fit``: :class:`.refine.PlaneTranslation`)."""
    T = prior.copy() if prior is not None else np.eye(4)
    cov = np.diag([bounds.rotation**2] * 3 + [bounds.translation**2] * 2)
    unresolved = RelativePose(T, cov, Status.UNRESOLVED, diagnostics=info)
    if not (cfg.odometry.wall_yaw and bound_by_prior and prior is not None):
        return unresolved
    yaw = wall_yaw(prev, curr, prior, cfg, bounds.translation)
    if yaw is None:
        return unresolved
    R, t = yaw_rotation(yaw[0]) @ prior[:3, :3], prior[:3, 3].copy()
    cov[2, 2], z_observed, sigma_z = yaw[1], False, np.inf
    if cfg.odometry.refinement != "none":
        refined = refine(prev, curr, R, t, False, bounds, cfg)
        R, fit = refined.R, refined.fit
        if fit.n_planes:
            t, cov[3:, 3:] = fit.t, fit.cov_xy
            if fit.z_observed:
                sigma_z, z_observed = fit.sigma_z, True
    ocfg = cfg.odometry
    cov = cov + pose_floor(ocfg.min_sigma_rotation_deg, ocfg.min_sigma_translation_m)
    ij = strict_association(prev, curr, R, cfg.association, t, bounds.translation)
    return RelativePose(make_transform(R, t), cov, Status.DEGENERATE, ij,
                        z_observed=z_observed, sigma_z=sigma_z, diagnostics=info)  # fmt: skip
