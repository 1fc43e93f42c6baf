"""The led twist's error as one unknown of the scan's registration (``planemap.lead_weights:
unknown``).

An epoch extracted again with a twist led from a measured step (``odometry.map_twist_lead``)
is deskewed with a twist whose error ``e`` (6,) has, per axis, the closed-form variance of
:mod:`planodom.odometry.led_variance`. That error is one for the whole scan: a plane seen
at time ``t`` is moved by ``t (e_w x p + e_v)``, each by its own time and place, so the
planes disagree among themselves in a pattern the error fixes. ``lead_weights: stated``
gives each plane the variance of its own share as if independent; here the error is
solved for instead: the continuous-time registration (:func:`.ctreg.register_twist`) of
the pose and a correction ``x`` of the twist used, with the zero-mean prior ``x ~ N(0,
diag(var))``. With many planes the correction is measured; where they do not observe it
the prior holds it at zero, and the pose is that of the registration alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from planodom.config import PlanemapConfig
from planodom.geometry import Plane
from planodom.odometry.planemap.ctreg import TwistRegistration, register_twist
from planodom.odometry.planemap.landmarks import PlaneMap
from planodom.odometry.planemap.register import Registration, ScanPlanes

#: the smallest prior sigma of a correction axis (rad/s or m/s): a variance stated zero
#: is not an infinite information (``ctreg``'s own floor).
MIN_SIGMA = 1e-9


def timed_planes(
    config: PlanemapConfig,
    cur: ScanPlanes,
    planes: Sequence[Plane],
    used: np.ndarray,
    led: tuple[np.ndarray, float] | None,
) -> ScanPlanes:
    """``cur`` with the ``used`` planes' time moments when the registration reads them
    (``twist_estimation`` not ``none``; ``lead_weights: unknown`` for a scan whose twist
    is led, ``led`` its variance (6,) and span) and every plane has them, and, with
    ``lead_weights: unknown``, the led twist's variance (``led_var``)."""
    unknown = config.lead_weights == "unknown" and led is not None
    if config.twist_estimation == "none" and not unknown:
        return cur
    tm = [planes[k].support.time_moments for k in used]
    if any(x is None for x in tm):
        return cur
    var = np.asarray(led[0], dtype=np.float64) if unknown and led is not None else None
    return replace(cur, time_moments=np.array(tm), led_var=var)


def led_registration(
    M: PlaneMap, reg: Registration, cur: ScanPlanes, iterations: int
) -> TwistRegistration | None:
    """The pose and the twist correction of a scan whose led twist's variance ``cur.led_var``
    is known (module docstring): :func:`.ctreg.register_twist` from ``reg`` with that
    variance as the correction's zero-mean prior; None without it, the time moments or
    3 inliers."""
    if cur.led_var is None or cur.time_moments is None:
        return None
    sd = np.maximum(np.sqrt(np.maximum(cur.led_var, 0.0)), MIN_SIGMA)
    return register_twist(M, reg, cur, cur.time_moments, sd, iterations)
