"""The streaming pass's extraction kept in a deskewing pass where the pass would deskew
the epoch alike (``odometry.deskew_pass_skip``: ``twist`` or ``planes``).

Each deskewing pass (:func:`planodom.odometry.run.redeskewed_run`) extracts every epoch
again, deskewed along the curve through the poses of the pass before; on the 2D rig that
is most of the passes' cost (docs/RESULTS.md P1MP14: ``p1mp`` at 2.8-3.0x the default's
CPU). Where the curve's twist over an epoch's sweep agrees with the twist the streaming
pass deskewed the epoch with, within the curve's own uncertainty, the pass has nothing
to tell the two deskewings apart by, and its extraction would differ from the streaming
one by that noise only. The pass's twist is the curve's secant over the points' times
(``deskew_times`` of the streaming result: the constant twist that moves the base frame
as the curve does over the sweep, in the deskewing's convention ``T_ref_t = exp(t xi)``,
:mod:`planodom.extraction.deskew`). Two chi-square tests of its difference ``dxi`` from
the streaming twist:

- ``twist``: against the curve's own uncertainty. Its variance is the curve's node
  variance at the epoch's middle (the step the sweep lies in, from the odometry's
  covariances, :func:`planodom.odometry.run.step_variances`) over the square of that
  step's time: a twist measured by one step. The streaming twist
  is the hypothesis tested, so its own uncertainty does not enter: the question is
  whether the pass can show it wrong.
- ``planes``: what the difference would do to the epoch's planes against their own
  noise. Deskewed with a twist off by ``dxi``, a plane fitted to the points moves by
  ``span D dxi`` to first order (``D`` its ``deskew_jacobian``, ``span = max |t|``,
  :mod:`planodom.odometry.plane_deskew`); the sum over the epoch's planes of that move's
  squared Mahalanobis distance under each plane's fit covariance (rank 3) is tested
  against the chi-square quantile of 3 DoF a plane: whether extracting again would move
  the planes by more than their range noise does.

Where the test passes, the pass takes the streaming pass's planes of the epoch, moved
from the epoch's time to the pass's reference time along the curve. An epoch without a
known deskewing twist (the first, after an unresolved one, or one whose planes were
extracted again later, ``superseded``) is always extracted again.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

from planodom.geometry import Plane, invert_transform, se3_log
from planodom.odometry.deskewed_epochs import Curve
from planodom.odometry.interpolate import curve_poses
from planodom.odometry.twist_sigma import chi2_quantile

if TYPE_CHECKING:
    from planodom.config import PlanodomConfig
    from planodom.odometry.run import OdometryRun


def curve_motion(curve: Curve, t_ref: float, t: float) -> np.ndarray:
    """``T_ref_t`` (4, 4): the base frame at the absolute time ``t`` (s) in the one at
    ``t_ref`` along ``curve``, from the one polynomial around their middle."""
    T = curve_poses(
        curve.times, curve.poses, 0.5 * (t_ref + t), np.array([t_ref, t]), curve.order,
        curve.variances, curve.n_fit, curve.increments,
    )  # fmt: skip
    return invert_transform(T[0]) @ T[1]


def curve_twist(curve: Curve, t0: float, t1: float) -> np.ndarray:
    """(6,) the curve's secant twist from ``t0`` to ``t1`` (absolute, s, ``t1 > t0``):
    ``se3_log(T_t0_t1) / (t1 - t0)``, rad/s and m/s, rotation first."""
    return se3_log(curve_motion(curve, t0, t1)) / (t1 - t0)


def twist_test(difference: np.ndarray, variance: np.ndarray, quantile: float) -> bool:
    """Whether ``difference`` (6,) is within its ``variance`` (6,) (per component; the
    components with a finite positive variance only) at the chi-square ``quantile``;
    False when no component has one (nothing to test by)."""
    ok = np.isfinite(variance) & (variance > 0)
    if not ok.any():
        return False
    d2 = float(np.sum(difference[ok] ** 2 / variance[ok]))
    return d2 <= chi2_quantile(quantile, int(ok.sum()))


def plane_test(planes: list[Plane], difference: np.ndarray, span: float, quantile: float) -> bool:
    """Whether moving ``planes`` by a deskewing twist off by ``difference`` (6,) (rad/s,
    m/s) over ``span`` s (``span D difference`` each, ``D`` its ``deskew_jacobian``) stays
    within their fit covariances at the chi-square ``quantile`` (3 DoF a plane, summed);
    False when a plane has no Jacobian or covariance, or there is none (nothing to test)."""
    if not planes or span <= 0:
        return False
    d2 = 0.0
    for p in planes:
        if p.deskew_jacobian is None or p.covariance is None:
            return False
        move = span * (np.asarray(p.deskew_jacobian) @ difference)
        d2 += float(move @ np.linalg.pinv(np.asarray(p.covariance), hermitian=True) @ move)
    return d2 <= chi2_quantile(quantile, 3 * len(planes))


def consistent_epochs(
    streaming: OdometryRun,
    curve: Curve,
    times: np.ndarray,
    variances: np.ndarray,
    quantile: float,
    mode: str = "twist",
) -> np.ndarray:
    """(N,) bool: the epochs whose streaming deskewing twist agrees with ``curve``'s over
    their sweep (module docstring).

    Args:
        streaming: the streaming pass's run (its results' ``deskew_twist`` and
            ``deskew_times``, its ``superseded``).
        curve: the pass's curve. times: (N,) epoch times, s.
        variances: (J, 6) the curve's node variances (rad^2, m^2), node k at the middle of
            epoch k (J = N or N - 1: the last epoch takes the last node's).
        quantile: the test's chi-square quantile. mode: ``twist`` or ``planes`` (module
            docstring; ``planes`` reads the streaming run's ``planes``).
    """
    times = np.asarray(times, dtype=np.float64)
    n = len(times)
    out = np.zeros(n, dtype=bool)
    if n < 2 or len(streaming.results) != n or len(variances) == 0:
        return out
    dt = np.diff(times)
    dt = np.r_[dt, dt[-1]]
    superseded = set(streaming.superseded)
    for k, r in enumerate(streaming.results):
        if r is None or r.deskew_twist is None or r.deskew_times is None or k in superseded:
            continue
        first, last = r.deskew_times
        if not (last > first and dt[k] > 0):
            continue
        twist = curve_twist(curve, times[k] + first, times[k] + last)
        if mode == "planes":
            span = max(abs(first), abs(last))  # the extraction's (plane_deskew.epoch_span)
            planes = streaming.planes[k] if len(streaming.planes) == n else []
            out[k] = plane_test(planes, twist - r.deskew_twist, span, quantile)
            continue
        variance = np.asarray(variances[min(k, len(variances) - 1)], dtype=np.float64) / dt[k] ** 2
        out[k] = twist_test(twist - r.deskew_twist, variance, quantile)
    return out


def moved_planes(planes: list[Plane], curve: Curve, t_k: float, reference: float) -> list[Plane]:
    """``planes`` (base frame at ``t_k``, s) in the base frame at ``reference`` (s) along
    ``curve`` (the same list's planes when the times are equal)."""
    if reference == t_k:
        return list(planes)
    T_ref_k = curve_motion(curve, reference, t_k)
    return [p.transformed(T_ref_k) for p in planes]


def reused_planes(
    streaming: OdometryRun,
    curve: Curve,
    times: np.ndarray,
    reference: np.ndarray,
    variances: np.ndarray,
    quantile: float,
    mode: str = "twist",
) -> Callable[[int], list[Plane] | None]:
    """``planes(k)``: the streaming planes of epoch k at ``reference[k]`` where
    :func:`consistent_epochs` holds, else None (extract it again)."""
    keep = consistent_epochs(streaming, curve, times, variances, quantile, mode)
    if len(streaming.planes) != len(keep):
        keep[:] = False

    def planes(k: int) -> list[Plane] | None:
        if not keep[k]:
            return None
        return moved_planes(streaming.planes[k], curve, float(times[k]), float(reference[k]))

    return planes


def pass_planes(
    config: PlanodomConfig,
    streaming: OdometryRun | None,
    curve: Curve,
    times: np.ndarray,
    reference: np.ndarray,
    variances: np.ndarray,
) -> Callable[[int], list[Plane] | None] | None:
    """:func:`reused_planes` under ``odometry.deskew_pass_skip`` (None: ``none``, or no
    streaming run to take planes from)."""
    mode = config.odometry.deskew_pass_skip
    if mode == "none" or streaming is None:
        return None
    quantile = config.odometry.deskew_pass_skip_quantile
    return reused_planes(streaming, curve, times, reference, variances, quantile, mode)
