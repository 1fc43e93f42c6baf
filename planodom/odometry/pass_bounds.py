"""The motion assumption of one pass of the pairwise solver (:mod:`.solver`).

With a prior (the constant-velocity prediction) the association is bounded by
``association.prior_translation_m`` / ``prior_rotation_deg`` around it, else by
``max_translation_m`` / ``max_rotation_deg`` around no motion. For
``odometry.refine_unmeasured: prediction`` it also carries what a direction the planes do
not measure keeps: the prior's translation and its variance (both passes: the retry
without the prior's bounds keeps the prediction too).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from planodom.angles import radians
from planodom.config import PlanodomConfig


class PassBounds(NamedTuple):
    """The motion assumption of one pass: centre ``t0`` (3,) m, translation bound m,
    rotation bound rad, the height to use when z is not measured, m, and, for
    ``refine_unmeasured: prediction`` with a prior of known sigma, the prior's translation
    (3,) m and its horizontal variance m^2, what an unmeasured direction keeps (else None)."""

    t0: np.ndarray
    translation: float
    rotation: float
    z_prior: float
    prediction: np.ndarray | None = None
    prediction_var: float | None = None


def pass_bounds(
    cfg: PlanodomConfig, prior: np.ndarray | None, bound_by_prior: bool, sigma: float | None
) -> PassBounds:
    """The bounds of a pass with the prior ``prior`` (4, 4) ``T_prev_curr`` or None,
    bounded by it or not, and ``sigma``: its translation's sigma, m (None: unknown)."""
    a, t_pred, var = cfg.association, None, None
    if cfg.odometry.refine_unmeasured == "prediction" and prior is not None:
        if sigma is not None and np.isfinite(sigma):
            t_pred, var = prior[:3, 3], sigma**2
    if bound_by_prior:
        assert prior is not None
        t0, t, r = prior[:3, 3], a.prior_translation_m, a.prior_rotation_deg
    else:
        t0, t, r = np.zeros(3), a.max_translation_m, a.max_rotation_deg
    z = float(prior[2, 3]) if prior is not None else 0.0
    return PassBounds(t0, t, radians(r), z, t_pred, var)
