"""The deskewing's rate refinement as a root search (``odometry.deskew_rate_solve``).

:func:`planodom.odometry.deskew.register_deskewed` extracts an epoch again with its own
twist: a fixed-point iteration ``r <- own(r)`` on the angular rate ``r`` it is deskewed
with. It converges where the step's rate depends weakly on the deskewing, and diverges
where it depends strongly: a degenerate step whose yaw rests on one far wall, which the
deskewing's rate error tilts (issue 11's 2D-rig world 6 at 6 mm, epoch 51, one wall 75 m
away: deskewed with 12.36 deg/s its own rate was 11.21, deskewed with 11.21 it was 8.04,
for a true 12.74; ``own(r) - r`` changed by 2.8 times what ``r`` did). The rate wanted is
the root of ``own(r) - r``; ``secant`` takes the secant step through the last two
``(r, own(r))`` per component (there 13.01 deg/s, the step's yaw 0.11 deg off instead of
0.94), at most twice as long as the plain step (two noisy points can be nearly level).
"""

from __future__ import annotations

import numpy as np

from planodom.config import OdometryConfig

#: The secant's step at most this many times the fixed-point step's length.
MAX_STEP_RATIO = 2.0


def secant_rate(
    new: np.ndarray, used: np.ndarray, own: np.ndarray, used0: np.ndarray, own0: np.ndarray
) -> np.ndarray:
    """(6,) ``new`` (the fixed-point refinement of ``used``, rad/s and m/s) with each
    angular-rate component it changed replaced by the secant root of ``own(r) - r``
    through ``(used0, own0)`` (the refinement before) and ``(used, own)``, its step from
    ``used`` at most :data:`MAX_STEP_RATIO` times ``|own - used|``; a component whose two
    points coincide (or are level) keeps ``new``'s. The velocity stays ``new``'s."""
    out = np.array(new, dtype=np.float64, copy=True)
    for i in range(3):
        g1, g0, dr = own[i] - used[i], own0[i] - used0[i], used[i] - used0[i]
        if new[i] == used[i] or dr == 0.0 or g1 == g0:
            continue
        limit = MAX_STEP_RATIO * abs(g1)
        out[i] = used[i] + np.clip(-g1 * dr / (g1 - g0), -limit, limit)
    return out


def solved_rate(
    new: np.ndarray,
    used: np.ndarray,
    own: np.ndarray,
    before: tuple[np.ndarray, np.ndarray] | None,
    config: OdometryConfig,
) -> np.ndarray:
    """(6,) the twist a refinement extracts again with under ``config.deskew_rate_solve``:
    ``new`` (the fixed point's, from ``used`` and ``own``), or with ``secant`` and the
    ``before`` refinement's (used, own) :func:`secant_rate`."""
    if before is None or config.deskew_rate_solve != "secant":
        return new
    return secant_rate(new, used, own, *before)


def epoch_deskew_config(config: OdometryConfig, gap: bool, pairwise: bool) -> OdometryConfig:
    """``config`` for one epoch's deskewing policy: no refinement after a ``gap`` in the
    epoch times (its step across the gap gives no twist to refine with), and the fixed
    point off the ``pairwise`` pipelines (``deskew_rate_solve: secant`` was measured on
    the 2D rig only); ``config`` itself otherwise."""
    changes: dict[str, object] = {"deskew_iterations": 0} if gap else {}
    if not pairwise and config.deskew_rate_solve != "fixed_point":
        changes["deskew_rate_solve"] = "fixed_point"
    return config.model_copy(update=changes) if changes else config
