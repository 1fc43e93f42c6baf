"""The deskewing error in a scan's registration weights (``planemap.deskew_variance``,
``planemap.lead_weights``).

A plane fitted to points deskewed with a twist off by ``dxi`` moves by ``span D dxi`` to
first order (``D`` (4, 6) its ``Plane.deskew_jacobian``, computed with the times over the
span ``max |t|``), so a twist error of covariance ``diag(var)`` gives its ``(n, d)`` the
covariance ``span^2 D diag(var) D^T``: a plane seen over a short time, or near the sensor,
carries little of it. ``deskew_variance: twist_change`` sizes the error by the
constant-velocity model's deviations so far (per epoch span, :func:`change_covariance`);
``lead_weights: stated`` by the led twist's own variance in closed form
(:mod:`planodom.odometry.led_variance`, :func:`led_weights`), and with it the scan's laser
bias is ``planemap.led_bias_m`` (the 2 cm of ``laser_bias_m`` also absorbs the deskewing
error); ``lead_weights: unknown`` keeps that bias but solves the error as one unknown of
the registration (:mod:`.led_twist`) instead of a term per plane.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planodom.config import PlanemapConfig
from planodom.geometry import Plane


def _jacobians(planes: Sequence[Plane], used: np.ndarray) -> np.ndarray:
    """(K, 4, 6) the ``used`` planes' deskewing Jacobians, zero where a plane has none."""
    J = np.zeros((len(used), 4, 6))
    for i, k in enumerate(used):
        if planes[k].deskew_jacobian is not None:
            J[i] = planes[k].deskew_jacobian
    return J


def change_covariance(
    config: PlanemapConfig,
    planes: Sequence[Plane],
    used: np.ndarray,
    dev_sse: np.ndarray,
    dev_n: np.ndarray,
) -> np.ndarray | None:
    """(K, 4, 4) covariance of the ``used`` planes' ``(n, d)`` from the deskewing twist's
    error (``planemap.deskew_variance: twist_change``), its variance per axis the mean
    square deviation of the prediction so far (``dev_sse`` (2,) summed squared rotation
    and translation deviations over ``dev_n`` (2,) epochs) over 3; None when off or before
    any motion was measured."""
    if config.deskew_variance == "off" or dev_n[0] == 0:
        return None
    rms = np.sqrt(dev_sse / np.maximum(dev_n, 1))
    per_axis = np.r_[np.full(3, rms[0] ** 2), np.full(3, rms[1] ** 2)] / 3.0
    J = _jacobians(planes, used)
    return np.einsum("kia,a,kja->kij", J, per_axis, J)


def led_weights(
    config: PlanemapConfig,
    planes: Sequence[Plane],
    used: np.ndarray,
    led: tuple[np.ndarray, float] | None,
) -> tuple[float, np.ndarray | None] | None:
    """(the laser bias, m; the (K, 4, 4) covariance of the ``used`` (K,) planes' ``(n, d)``
    from the led twist's error ``led`` = (its variance (6,) per axis, (rad/s)^2 and
    (m/s)^2; the scan's span, s)), or None when ``lead_weights`` is off or the scan's twist
    is not led (then weighted as without it). With ``lead_weights: unknown`` no
    covariance (None): the error is the registration's unknown (:mod:`.led_twist`)."""
    if config.lead_weights == "off" or led is None:
        return None
    if config.lead_weights == "unknown":
        return config.led_bias_m, None
    var, span = led
    J = _jacobians(planes, used)
    return config.led_bias_m, span**2 * np.einsum("kia,a,kja->kij", J, var, J)
